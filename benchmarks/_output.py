"""What every benchmark script ends with: its table, and with ``--json`` one JSON line last."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable


def parser(doc: str) -> argparse.ArgumentParser:
    """The benchmark's argument parser, with the ``--json`` flag every script has."""
    out = argparse.ArgumentParser(description=doc.splitlines()[0])
    out.add_argument("--json", action="store_true", help="print one JSON value as the last line")
    return out


def finish(result, table: Callable[..., str], as_json: bool) -> int:
    """Print ``table(result)``, then ``result`` as one JSON line when asked; exit code 0."""
    print(table(result))
    if as_json:
        print(json.dumps(result))
    return 0
