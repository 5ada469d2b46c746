"""Text exports of data loggers: find the dialect (delimiter, decimal mark, header, units row).

Loggers write CSV their own way: free-text lines above the header (rig, test, date), a
row of units below it, ``;`` with a decimal comma (European locales), tabs or spaces,
``#`` comments. :func:`read_text_table` finds all of that from the file itself:

1. the data block is the longest run of lines at the end of the file whose fields, under
   some (delimiter, decimal mark), are all numbers (empty and NaN allowed), in one
   constant count; among the dialects that parse it, the one with the most fields wins,
   then ``.`` over ``,`` as decimal mark;
2. the header is the non-numeric line above the data with that field count that holds
   the most of the names asked for (else the first such line); lines between it and the
   data are unit rows, lines above it the preamble.

A :class:`CsvOptions` (the column map's ``csv:``) states any of these instead. A file
whose last line is cut (no final newline and a last field shorter than its column's
usual number of decimals, or fewer fields) is refused naming the line.
"""

from __future__ import annotations

import io
import re
from pathlib import Path
from typing import Literal, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from ..errors import InputError

DELIMITERS = {",": ",", ";": ";", "tab": "\t", "space": None}
TAIL_LINES = 200  # lines from the end that decide the dialect
HEAD_LINES = 400  # lines from the start searched for the header
_NUMBER = {
    ".": re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$"),
    ",": re.compile(r"^[+-]?(\d+,?\d*|,\d+)([eE][+-]?\d+)?$"),
}
_MISSING = {"", "nan", "NaN", "NAN", "-nan", "NA", "N/A", "null", "NULL", "-", "--"}


class CsvOptions(BaseModel):
    """What the column map may state about a text file (``csv:``); omitted: detected."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    delimiter: Literal[",", ";", "tab", "space"] | None = Field(
        None, description="field separator; omitted: detected"
    )
    decimal: Literal[".", ","] | None = Field(None, description="decimal mark; omitted: detected")
    header_line: int | None = Field(
        None, ge=1, description="1-based line number of the header (column names); omitted: found"
    )
    units_lines: int | None = Field(
        None,
        ge=0,
        le=10,
        description="lines between the header and the data (units rows); omitted: found",
    )
    encoding: str = Field("utf-8", description="text encoding (latin-1 is tried when utf-8 fails)")


class Dialect(NamedTuple):
    delimiter: str | None  # None: runs of white space
    decimal: str
    header: int  # 0-based line index of the header
    data: int  # 0-based line index of the first data line
    fields: int


def _split(line: str, delimiter: str | None) -> list[str]:
    parts = line.split() if delimiter is None else line.split(delimiter)
    return [p.strip().strip('"').strip() for p in parts]


def _is_number(text: str, decimal: str) -> bool:
    return text in _MISSING or bool(_NUMBER[decimal].match(text))


def _numeric(fields: list[str], decimal: str) -> bool:
    """A data row: at least one number, and at least half of its fields numbers (a text
    column is named later, by the column it is in)."""
    numbers = sum(f not in _MISSING and bool(_NUMBER[decimal].match(f)) for f in fields)
    return numbers >= 1 and 2 * sum(_is_number(f, decimal) for f in fields) >= len(fields)


def _candidates(options: CsvOptions) -> list[tuple[str | None, str]]:
    delimiters = (
        [DELIMITERS[options.delimiter]] if options.delimiter is not None else [",", ";", "\t", None]
    )
    decimals = [options.decimal] if options.decimal is not None else [".", ","]
    return [(d, m) for d in delimiters for m in decimals if not (d == "," and m == ",")]


def _trailing_rows(lines: list[str], delimiter: str | None, decimal: str) -> tuple[int, int]:
    """(count, run): the field count of the last line and how many lines at the end of the
    file (at most :data:`TAIL_LINES`) are data rows of that count."""
    count = len(_split(lines[-1], delimiter))
    run = 0
    for line in reversed(lines[-TAIL_LINES:]):
        fields = _split(line, delimiter)
        if len(fields) != count or not _numeric(fields, decimal):
            break
        run += 1
    return count, run


def detect(lines: list[str], wanted: list[str], options: CsvOptions, path: Path) -> Dialect:
    """The file's dialect (module docstring); ``lines`` without comments and blank lines."""
    best = None
    for delimiter, decimal in _candidates(options):
        # the last line may be cut: judge from the line before it when there is one
        body = lines[:-1] if len(lines) > 2 else lines
        count, run = _trailing_rows(body, delimiter, decimal)
        if count < 2 or run < min(3, len(body)):
            continue
        key = (min(run, TAIL_LINES), count, decimal == ".")
        if best is None or key > best[0]:
            best = (key, delimiter, decimal, count)
    if best is None:
        raise InputError(
            path,
            "is not a table of numbers this reader can find: its last lines do "
            "not split into the same number of numeric fields with ',', ';', tab or "
            "spaces and '.' or ',' as decimal mark; state the dialect in the column "
            "map (csv: {delimiter: ';', decimal: ',', header_line: N})",
            "csv",
        )
    _, delimiter, decimal, count = best
    if options.header_line is not None:
        header = options.header_line - 1
        if header >= len(lines):
            raise InputError(
                path,
                f"has only {len(lines)} non-comment lines; csv.header_line "
                f"{options.header_line} is past the end",
                "csv.header_line",
            )
        data = header + 1 + (options.units_lines or 0)
        if options.units_lines is None:  # unit rows: the non-numeric lines below the header
            while data < len(lines) and not _numeric(_split(lines[data], delimiter), decimal):
                data += 1
        return Dialect(delimiter, decimal, header, data, count)
    first = next(
        (
            k
            for k, line in enumerate(lines[:HEAD_LINES])
            if len(_split(line, delimiter)) == count and _numeric(_split(line, delimiter), decimal)
        ),
        None,
    )
    if first is None:
        first = len(lines) - _trailing_rows(lines, delimiter, decimal)[1]
    above = [k for k in range(first) if len(_split(lines[k], delimiter)) == count]
    if not above:
        raise InputError(
            path,
            "has no header line (column names) above its numbers; a "
            "recording names its columns in a header (or state csv.header_line)",
            "csv",
        )

    def hits(k: int) -> int:
        names = set(_split(lines[k], delimiter))
        return sum(w in names for w in wanted)

    header = max(above, key=lambda k: (hits(k), -k))
    if options.units_lines is not None:
        first = header + 1 + options.units_lines
    elif first < header + 1:
        first = header + 1
    return Dialect(delimiter, decimal, header, first, count)


def _decimals(text: str, decimal: str) -> int:
    mantissa = re.split(r"[eE]", text)[0]
    return len(mantissa.split(decimal)[1]) if decimal in mantissa else 0


def _value(text: str, decimal: str) -> float:
    return float(text.replace(",", ".") if decimal == "," else text)


def _digits(text: str) -> int:
    return sum(ch.isdigit() for ch in re.split(r"[eE]", text)[0])


def _check_last_line(raw: str, lines: list[str], dialect: Dialect, path: Path, line_no: int):
    """A file without a final newline whose last line is shorter than its rows: cut."""
    if raw.endswith(("\n", "\r")):
        return
    last = _split(lines[-1], dialect.delimiter)
    cut = len(last) != dialect.fields
    if not cut:
        previous = [_split(line, dialect.delimiter) for line in lines[-21:-1]]
        for j, text in enumerate(last):
            column = [
                p[j]
                for p in previous
                if len(p) > j and _is_number(p[j], dialect.decimal) and p[j] not in _MISSING
            ]
            if not column or text in _MISSING or not _is_number(text, dialect.decimal):
                continue
            if _decimals(text, dialect.decimal) < min(
                _decimals(c, dialect.decimal) for c in column
            ):
                cut = True  # fewer decimals than the logger ever writes in this column
            values = np.array([_value(c, dialect.decimal) for c in column])
            step = float(np.median(np.abs(np.diff(values)))) if values.size > 2 else 0.0
            value = _value(text, dialect.decimal)
            if _digits(text) < _digits(column[-1]) and abs(value - values[-1]) > 10.0 * max(
                step, 10.0 ** -_decimals(text, dialect.decimal)
            ):
                cut = True  # a digit lost: far off the column's course
    if cut:
        raise InputError(
            path,
            f"its last line (line {line_no}) looks cut: the file ends without "
            "a newline inside a row whose last field is shorter than the rows "
            "before it (a recording still being written, or truncated); remove "
            "that line or copy the complete file",
            "csv",
        )


def read_text_table(
    path: Path, wanted: list[str], options: CsvOptions
) -> tuple[dict[str, np.ndarray], dict]:
    """Columns by header name (float arrays, NaN where missing) and what was detected."""
    import pandas as pd

    data = path.read_bytes()
    try:
        raw = data.decode(options.encoding)
    except (UnicodeDecodeError, LookupError):
        raw = data.decode("latin-1")
    raw = raw.lstrip("\ufeff")
    numbered = [
        (k + 1, line)
        for k, line in enumerate(raw.splitlines())
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not numbered:
        raise InputError(path, "is empty (no line of data)")
    line_numbers = [n for n, _ in numbered]
    lines = [line for _, line in numbered]
    dialect = detect(lines, wanted, options, path)
    names = _split(lines[dialect.header], dialect.delimiter)
    body = lines[dialect.data :]
    if not body:
        raise InputError(path, "has a header but no rows of numbers below it")
    _check_last_line(raw, body, dialect, path, line_numbers[-1])
    for offset, line in enumerate(body):
        if len(_split(line, dialect.delimiter)) != dialect.fields:
            shown = line if len(line) < 80 else line[:77] + "..."
            raise InputError(
                path,
                f"line {line_numbers[dialect.data + offset]} does not have "
                f"the {dialect.fields} fields of the header ('{shown}'); cut the "
                "recording to its table of numbers",
                "csv",
            )
    text = "\n".join(body)
    try:
        frame = pd.read_csv(
            io.StringIO(text),
            sep=dialect.delimiter or r"\s+",
            header=None,
            names=range(dialect.fields),
            dtype=str,
            keep_default_na=False,
            engine="c" if dialect.delimiter else "python",
        )
    except (ValueError, pd.errors.ParserError) as exc:
        raise InputError(
            path, f"is not a readable table of numbers ({str(exc).splitlines()[0]})", "csv"
        ) from None
    columns: dict[str, np.ndarray] = {}
    for j, name in enumerate(names):
        if name and name not in columns:
            columns[name] = _to_numbers(frame[j].str.strip().str.strip('"'), dialect.decimal)
    units = {}
    if dialect.data > dialect.header + 1:
        row = _split(lines[dialect.header + 1], dialect.delimiter)
        units = {name: unit for name, unit in zip(names, row) if unit}
    detected = {
        "delimiter": {",": ",", ";": ";", "\t": "tab", None: "space"}[dialect.delimiter],
        "decimal": dialect.decimal,
        "header_line": line_numbers[dialect.header],
        "first_data_line": line_numbers[dialect.data],
        "preamble_lines": dialect.header,
        "units_lines": dialect.data - dialect.header - 1,
    }
    return columns, {"dialect": detected, "units_row": units}


def _to_numbers(cells, decimal: str) -> np.ndarray:
    """A column's cells as float64 (NaN where missing); a column with text left as text
    (the reader names it when it is mapped)."""
    import pandas as pd

    missing = cells.isin(_MISSING)
    if decimal == ",":
        cells = cells.str.replace(",", ".", regex=False)
    values = pd.to_numeric(cells.where(~missing, "nan"), errors="coerce")
    if bool((values.isna() & ~missing).any()):
        return cells.to_numpy(dtype=object)
    return values.to_numpy(dtype=np.float64)


def unit_of(text: str) -> str:
    """A units-row cell as a unit name: brackets and case folded (``[deg]`` -> ``deg``)."""
    return text.strip().strip("[]()").strip()
