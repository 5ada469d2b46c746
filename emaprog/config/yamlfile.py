"""Reading a YAML file into a mapping, with every failure as an InputError."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from ..errors import InputError


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that refuses duplicate keys instead of keeping the last one."""


def _construct_mapping(loader: yaml.SafeLoader, node: yaml.MappingNode, deep: bool = False):
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key '{key}'", key_node.start_mark
            )
        seen.add(key)
    return loader.construct_mapping(node, deep=deep)


# YAML 1.2 floats: PyYAML (YAML 1.1) reads "3e5" or "4.0e-4"-less-dot forms as text.
_FLOAT_12 = re.compile(
    r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
    |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""",
    re.X,
)
_UniqueKeyLoader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag != "tag:yaml.org,2002:float"]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_UniqueKeyLoader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_12, list("-+0123456789."))

_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def load_mapping(path: str | Path) -> dict[str, Any]:
    """Load a YAML file whose top level must be a mapping.

    Raises
    ------
    InputError
        Missing or unreadable file, binary content, YAML syntax error,
        duplicate key, empty document, or a top level that is not a mapping.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except IsADirectoryError:
        raise InputError(path, "is a directory, expected a YAML file") from None
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror})") from None
    if b"\x00" in raw:
        raise InputError(path, "is a binary file, expected YAML text")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(path, "is not UTF-8 text, expected YAML") from None
    return parse_mapping(text, path)


def parse_mapping(text: str, source: str | Path) -> dict[str, Any]:
    """Parse YAML text whose top level must be a mapping with string keys."""
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 (safe loader subclass)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise InputError(source, f"YAML syntax error{where}: {exc.problem}") from None
    except yaml.YAMLError as exc:
        raise InputError(source, f"YAML error: {exc}") from None
    if data is None:
        raise InputError(source, "is empty, expected a YAML mapping")
    if not isinstance(data, dict):
        raise InputError(
            source, f"top level is a {type(data).__name__}, expected a mapping of keys"
        )
    bad = [k for k in data if not isinstance(k, str)]
    if bad:
        raise InputError(source, f"keys must be text, got {bad[0]!r}")
    return data


def catalogue_fields(fields: dict[str, Any]) -> dict[str, Any]:
    """Field definitions of a pydantic model built from the fault catalogue at import
    (``create_model``'s keyword arguments, typed for it)."""
    return fields
