"""The one error type that reaches the user as "invalid input" (exit code 2)."""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Iterable, Sequence
from pathlib import Path

from pydantic import ValidationError


class InputError(Exception):
    """Invalid user input: names the file, the key path and what is allowed.

    Parameters
    ----------
    source : str or Path
        The file (or other input) that is wrong.
    message : str
        What is wrong and what is allowed.
    key : str, optional
        Dotted key path inside the file, e.g. ``command.start_frequency``.
    """

    def __init__(self, source: str | Path, message: str, key: str | None = None):
        self.source = str(source)
        self.key = key
        self.message = message
        where = f"{self.source}: {key}: " if key else f"{self.source}: "
        super().__init__(where + message)


def past_limit(value: float, limit: float, spec: str) -> str:
    """``value`` in the format ``spec`` (``.N%``, ``.Nf``, ``.Ng`` or ``.Ne``) with as many
    more digits as it takes not to read as ``limit``: a value refused for lying past its
    limit must not print as the limit itself ("misses 10 % (at most 10 %)" for 0.1004)."""
    match = re.fullmatch(r"\.(\d+)([%fge])", spec)
    if match is None:
        raise ValueError(f"format {spec!r} is not .N%, .Nf, .Ng or .Ne")
    digits, kind = int(match.group(1)), match.group(2)
    scale = 100.0 if kind == "%" else 1.0
    text = format(value, spec)
    for extra in range(1, 7):
        if value == limit or not math.isclose(float(text.rstrip("%")) / scale, limit):
            break
        text = format(value, f".{digits + extra}{kind}")
    return text


def key_path(loc: Sequence[str | int], tags: Iterable[str] = ()) -> str:
    """Dotted key path from a pydantic error location, without union tags."""
    tags = set(tags)
    parts = []
    for item in loc:
        if isinstance(item, int):
            parts.append(f"[{item}]")
        elif item not in tags:
            parts.append(("." if parts else "") + item)
    return "".join(parts) or "(top level)"


def _suggestion(name: str, allowed: Iterable[str]) -> str:
    close = difflib.get_close_matches(name, list(allowed), n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


def from_validation_error(
    source: str | Path, error: ValidationError, model: type, tags: Iterable[str] = ()
) -> InputError:
    """Turn the first pydantic error into an :class:`InputError`.

    Unknown keys get the list of allowed keys at that level and the closest
    match, so a misspelt key says what was meant.
    """
    errors = error.errors(include_url=False)
    # a misspelt key also makes its intended key "missing": report the misspelling
    first = min(errors, key=lambda e: e["type"] != "extra_forbidden")
    loc = tuple(first["loc"])
    path = key_path(loc, tags)
    if first["type"] == "extra_forbidden":
        allowed = _allowed_keys(model, loc[:-1], tags)
        name = str(loc[-1])
        hint = _suggestion(name, allowed)
        listing = ", ".join(sorted(allowed)) if allowed else "none"
        return InputError(source, f"unknown key '{name}'{hint} (allowed here: {listing})", path)
    message = first["msg"].removeprefix("Value error, ")
    given = first.get("input")
    if first["type"] not in ("missing",) and not isinstance(given, (dict, list)):
        message += f" (got {given!r})"
    return InputError(source, message, path)


def _allowed_keys(model: type, loc: Sequence[str | int], tags: Iterable[str]) -> list[str]:
    """Field names of the nested model reached by ``loc`` (best effort). A tag in ``loc``
    (a tagged union's ``kind``) picks the union member of that kind, so that a typo inside
    a chirp command lists the chirp's keys, not the first member's."""

    tags = set(tags)
    annotation: object = model
    for item in loc:
        if isinstance(item, int):
            continue
        if item in tags:
            annotation = _member_of_kind(annotation, item) or annotation
            continue
        current = _model_of(annotation)
        if current is None:
            return []
        field = current.model_fields.get(item)
        if field is None:
            return []
        annotation = field.annotation
    current = _model_of(annotation)
    return list(current.model_fields) if current is not None else []


def _members(annotation) -> list:
    from typing import get_args

    from pydantic import BaseModel

    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in get_args(annotation) for m in _members(arg)]


def _member_of_kind(annotation, tag: str):
    """The member of a tagged union whose ``kind`` literal is ``tag``."""
    from typing import get_args

    for member in _members(annotation):
        kind = member.model_fields.get("kind")
        if kind is not None and tag in get_args(kind.annotation):
            return member
    return None


def _model_of(annotation):
    members = _members(annotation)
    return members[0] if members else None
