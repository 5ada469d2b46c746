"""Trace <-> Parquet, with per-column units and the ``emaprog`` provenance JSON (docs/reference.md, Traces)."""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ..errors import InputError

if TYPE_CHECKING:
    import pandas as pd

#: Every trace column: unit and description. The single table of record.
COLUMNS: dict[str, tuple[str, str]] = {
    "time": ("s", "sample instant"),
    "command": ("rad", "position command on the surface angle"),
    "position": ("rad", "measured surface angle"),
    "speed": ("rad/s", "measured motor speed"),
    "current": ("A", "equivalent current (|Ia|+|Ib|+|Ic|)/2 sign(T_M)"),
    "current_a": ("A", "phase A current"),
    "current_b": ("A", "phase B current"),
    "current_c": ("A", "phase C current"),
    "torque": ("N m", "motor electromagnetic torque"),
    "motor_angle": ("rad", "motor mechanical angle"),
}
REQUIRED = ("time", "command", "position", "speed", "current")
REFERENCE_EXTRA = ("current_a", "current_b", "current_c", "torque", "motor_angle")
METADATA_KEY = b"emaprog"


@dataclass(frozen=True)
class Trace:
    """A sampled run: named float64 columns on a common time grid, plus provenance."""

    columns: dict[str, np.ndarray]
    metadata: dict[str, Any] | None = field(default=None)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    @property
    def time(self) -> np.ndarray:
        return self.columns["time"]

    @property
    def sample_rate(self) -> float:
        return 1.0 / float(np.median(np.diff(self.time)))


def write_trace(path: str | Path, trace: Trace) -> Path:
    """Write atomically (temporary name, then rename) with units and provenance."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fields, arrays = [], []
    for name in trace.columns:
        unit, description = COLUMNS[name]
        fields.append(
            pa.field(
                name,
                pa.float64(),
                nullable=False,
                metadata={b"unit": unit.encode(), b"description": description.encode()},
            )
        )
        arrays.append(pa.array(np.asarray(trace.columns[name], dtype=np.float64)))
    meta = {METADATA_KEY: json.dumps(trace.metadata).encode()} if trace.metadata else None
    table = pa.Table.from_arrays(arrays, schema=pa.schema(fields, metadata=meta))
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        pq.write_table(table, tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def _require_columns(names, source: str | Path) -> None:
    missing = [c for c in REQUIRED if c not in names]
    if missing:
        raise InputError(
            source,
            f"missing column(s) {', '.join(missing)}; a trace needs "
            f"{', '.join(REQUIRED)} (docs/reference.md, Traces)",
        )


def check_columns(raw: dict[str, Any], source: str | Path) -> dict[str, np.ndarray]:
    """The contract columns of a trace, checked; any problem is an :class:`InputError`.

    The required trace columns (docs/reference.md, Traces) present, numeric and finite, at least 10 samples,
    strictly increasing and uniformly spaced time. Foreign extra columns are
    ignored, never guessed at.
    """
    _require_columns(raw, source)
    columns = {}
    for name, values in raw.items():
        if name not in COLUMNS:
            continue
        values = np.asarray(values)
        if values.dtype.kind not in "fiu":
            raise InputError(source, f"column has type {values.dtype}, expected float64", name)
        values = values.astype(np.float64)
        if not np.all(np.isfinite(values)):
            raise InputError(source, "column holds NaN or infinite values", name)
        columns[name] = values
    check_time(columns["time"], source)
    return columns


#: [-] Jitter of the sampling period allowed in a trace or recording (of the median period):
#: the 1 ms error filter is a moving average over samples, so they must be evenly spaced.
JITTER = 0.1


def check_time(t: np.ndarray, source: str | Path, key: str = "time") -> None:
    """Sample instants a trace may have: at least 10, strictly increasing, evenly spaced
    within :data:`JITTER`, no gap. The message names the first offending row (0-based,
    data rows) and its time."""
    if t.size < 10:
        raise InputError(source, f"only {t.size} samples; at least 10 are needed", key)
    dt = np.diff(t)
    period = float(np.median(dt))
    if not period > 0:
        raise InputError(source, "time must increase strictly from sample to sample", key)
    # time going back or standing still is the first thing to say: it makes other spacings odd
    bad = np.flatnonzero(dt <= 0)
    if bad.size == 0:
        bad = np.flatnonzero(np.abs(dt - period) > JITTER * period)
    if bad.size == 0:
        return
    k = int(bad[0])
    where = f"at row {k + 1} (time {t[k + 1]:.9g} s)"
    if dt[k] == 0:
        problem = (
            f"duplicated sample {where}: the same time as the row before; remove "
            "repeated rows from the recording"
        )
    elif dt[k] < 0:
        problem = f"time must increase strictly from sample to sample; it goes back {where}"
    elif dt[k] > 1.5 * period:
        problem = (
            f"gap of {dt[k]:.6g} s {where} in a recording sampled every {period:.6g} s; "
            "identify a continuous stretch (cut the recording at the gap)"
        )
    else:
        problem = (
            f"samples must be evenly spaced (within {JITTER:.0%} of the median period "
            f"{period:.6g} s); the spacing is {dt[k]:.6g} s {where}"
        )
    raise InputError(source, problem, key)


def read_trace(path: str | Path) -> Trace:
    """Read and validate a trace; any problem is an :class:`InputError`.

    Checks: a readable Parquet file, the required trace columns (docs/reference.md, Traces), float64
    (or losslessly castable numeric) values, all finite, at least 10 samples,
    strictly increasing and uniformly spaced time. A trace without ``emaprog``
    metadata (a rig recording) is valid.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "trace file not found")
    try:
        table = pq.read_table(path)
    except (pa.ArrowInvalid, OSError) as exc:
        hint = (
            ""
            if path.suffix.lower() == ".parquet"
            else "; a data logger's file (CSV, MATLAB, TDMS) is read through a column map: "
            "give --columns MAP.yaml (docs/reference.md, Rig recordings)"
        )
        raise InputError(
            path, f"is not a readable Parquet trace ({str(exc).splitlines()[0]})" + hint
        ) from None
    _require_columns(table.column_names, path)
    raw_columns = {}
    for name in table.column_names:
        col = table.column(name)
        if name in COLUMNS and not (
            pa.types.is_floating(col.type) or pa.types.is_integer(col.type)
        ):
            raise InputError(path, f"column has type {col.type}, expected float64", name)
        if name in COLUMNS and col.null_count:
            raise InputError(path, f"column has {col.null_count} missing values", name)
        raw_columns[name] = col.to_numpy() if name in COLUMNS else None
    columns = check_columns(raw_columns, path)
    metadata = None
    raw = (table.schema.metadata or {}).get(METADATA_KEY)
    if raw is not None:
        try:
            metadata = json.loads(raw)
        except (json.JSONDecodeError, UnicodeDecodeError):
            raise InputError(path, "the 'emaprog' metadata is not valid JSON") from None
        if not isinstance(metadata, dict):
            raise InputError(path, "the 'emaprog' metadata must be a JSON object")
    return Trace(columns, metadata)


def frame_of(trace: Trace) -> pd.DataFrame:
    """A trace as a DataFrame: ``attrs["units"]`` per column, ``attrs["emaprog"]`` provenance."""
    import pandas as pd

    frame = pd.DataFrame(
        {name: np.asarray(values, float) for name, values in trace.columns.items()}
    )
    frame.attrs["units"] = {name: COLUMNS[name][0] for name in trace.columns}
    frame.attrs["emaprog"] = trace.metadata
    return frame


def trace_of(frame: pd.DataFrame, source: str | Path = "trace") -> Trace:
    """A DataFrame (from :func:`frame_of`, or a recording with the contract columns) as a Trace.

    Checked like a file (:func:`check_columns`); provenance from ``attrs["emaprog"]``.
    """
    columns = {str(name): frame[name].to_numpy() for name in frame.columns}
    return Trace(check_columns(columns, source), frame.attrs.get("emaprog"))


def column_units(path: str | Path) -> dict[str, str]:
    """Units stored in the Arrow field metadata of a trace file."""
    schema = pq.read_schema(path)
    return {f.name: (f.metadata or {}).get(b"unit", b"").decode() for f in schema}


def write_json(path: str | Path, data: dict) -> Path:
    """Write JSON atomically (temporary name, then rename)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(json.dumps(data, indent=2, default=float) + "\n")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def writable_output(
    path: str | Path, kind: str, force: bool = False, protected: tuple[str, ...] | bool = ()
) -> Path:
    """Refuse, before any work, an output that cannot be written (exit 2 naming it).

    ``kind`` ``file``: not an existing folder; ``folder``: not an existing file. Without
    ``force`` a protected output that exists is refused rather than overwritten:
    ``protected=True`` for a file (a unit set), or the names of the results a folder holds
    (a report). The nearest existing parent must be a writable folder; nothing is created.
    """
    path = Path(path)
    if kind == "file" and path.is_dir():
        raise InputError(
            path,
            f"is an existing folder; give the file to write (e.g. {path / 'out.parquet'})",
            "--output",
        )
    if kind == "folder" and path.exists() and not path.is_dir():
        raise InputError(
            path, "is an existing file; give a folder to write the results in", "--output"
        )
    if not force and protected:
        if isinstance(protected, bool):
            existing = [path] if path.is_file() else []
        else:
            existing = [path / name for name in protected if (path / name).exists()]
        if existing:
            raise InputError(
                existing[0],
                "exists already; it is not overwritten without "
                "--force (or choose another --output)",
                "--output",
            )
    parent = path if kind == "folder" else path.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise InputError(path, f"cannot be written: {parent} is not a folder", "--output")
    try:  # a probe file, removed at once: permissions, read-only file systems, quotas
        handle, probe = tempfile.mkstemp(prefix=".emaprog-probe-", dir=parent)
        os.close(handle)
        os.unlink(probe)
    except OSError as exc:
        raise InputError(
            path,
            f"cannot be written: {parent} is not a writable folder ({exc.strerror})",
            "--output",
        ) from None
    return path
