"""Rig recordings: CSV, MATLAB ``.mat`` and foreign Parquet files read through a column map.

A data logger names and scales its channels its own way (``pos_deg``,
``speed_rpm``, phase currents in mA...). A column map (YAML) says, for each
trace column of the contract, the source column and its unit::

    time: {column: t_s, unit: s}
    command: {column: cmd_deg, unit: deg}
    position: {column: pos_deg, unit: deg}
    speed: {column: speed_rpm, unit: rpm}
    current_a: {column: ia_A, unit: A}
    current_b: {column: ib_A, unit: A}
    current_c: {column: ic_A, unit: A}

:func:`read_recording` turns a recording into a contract :class:`Trace` (SI
units, time from 0, provenance naming the source file, its SHA-256 and the
map). A recording without an equivalent-current column gets one from its phase
currents, ``(|I_A| + |I_B| + |I_C|) / 2`` signed like the motor torque: the
recorded torque's sign when the map has ``torque``, else the sign of the
current demand of the actuator's own controller replayed on the recorded
command, position and speed (the hysteresis regulator makes the pair current,
hence the torque, follow that demand's sign; a hinge moment does not fool it,
unlike a sign taken from the acceleration).
"""

from __future__ import annotations

import csv
import hashlib
import math
from pathlib import Path
from typing import Any, Optional

import numpy as np
from pydantic import (BaseModel, ConfigDict, Field, ValidationError, ValidationInfo, field_validator,
                      model_validator)

from .. import __version__
from ..config.parameters import Parameters
from ..config.yamlfile import load_mapping
from ..errors import InputError, from_validation_error
from .storage import COLUMNS, Trace, check_columns

#: Units a column map may give, by the kind of quantity: factor to SI.
UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3},
    "angle": {"rad": 1.0, "deg": math.pi / 180.0, "mrad": 1e-3},
    "speed": {"rad/s": 1.0, "rpm": 2.0 * math.pi / 60.0, "deg/s": math.pi / 180.0},
    "current": {"A": 1.0, "mA": 1e-3},
    "torque": {"N m": 1.0},
}
#: The kind of quantity of each contract column.
KIND = {"time": "time", "command": "angle", "position": "angle", "speed": "speed",
        "current": "current", "current_a": "current", "current_b": "current",
        "current_c": "current", "torque": "torque", "motor_angle": "angle"}
PHASE_COLUMNS = ("current_a", "current_b", "current_c")
FORMATS = {".csv": "csv", ".txt": "csv", ".mat": "mat", ".parquet": "parquet"}


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Column(_Strict):
    """Where one contract column is in the recording, and its unit there."""

    column: str = Field(min_length=1, description="name of the column (CSV header, MATLAB "
                                                  "variable or struct field, Parquet column)")
    unit: str = Field(description="its unit (UNITS per kind of quantity)")


class ColumnMap(_Strict):
    """Contract column -> source column and unit; ``variable``: the MATLAB struct holding them."""

    time: Column
    command: Column
    position: Column
    speed: Column
    current: Optional[Column] = None
    current_a: Optional[Column] = None
    current_b: Optional[Column] = None
    current_c: Optional[Column] = None
    torque: Optional[Column] = None
    motor_angle: Optional[Column] = None
    variable: Optional[str] = Field(None, min_length=1, description="MATLAB files: the struct "
                                    "whose fields are the columns (omitted: top-level variables)")

    @field_validator(*KIND)
    @classmethod
    def _unit_allowed(cls, value: Column | None, info: ValidationInfo):
        if value is None:
            return value
        allowed = UNITS[KIND[info.field_name]]
        if value.unit not in allowed:
            raise ValueError(f"unit '{value.unit}' is not allowed for {info.field_name} "
                             f"(allowed: {', '.join(allowed)})")
        return value

    @model_validator(mode="after")
    def _some_current(self):
        phases = [getattr(self, p) is not None for p in PHASE_COLUMNS]
        if self.current is None and not all(phases):
            raise ValueError("map either current (the equivalent current) or all of current_a, "
                             "current_b, current_c (it is then computed)")
        return self

    def mapped(self) -> dict[str, Column]:
        return {key: getattr(self, key) for key in KIND if getattr(self, key) is not None}


def load_column_map(path: str | Path) -> ColumnMap:
    """Load and validate a column map YAML; any problem is an InputError naming the key."""
    path = Path(path)
    try:
        return ColumnMap.model_validate(load_mapping(path))
    except ValidationError as exc:
        raise from_validation_error(path, exc, ColumnMap) from None


# ---------------------------------------------------------------- file formats
def _read_csv(path: Path) -> dict[str, np.ndarray]:
    import pandas as pd

    with open(path, newline="", encoding="utf-8", errors="replace") as handle:
        head = handle.read(4096)
    try:
        delimiter = csv.Sniffer().sniff(head, delimiters=",;\t ").delimiter
    except csv.Error:
        delimiter = ","
    try:
        frame = pd.read_csv(path, sep=delimiter, comment="#")
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(path, f"is not a readable CSV recording ({str(exc).splitlines()[0]})") from None
    frame.columns = [str(c).strip() for c in frame.columns]
    return {name: frame[name].to_numpy() for name in frame.columns}


def _read_parquet(path: Path) -> dict[str, np.ndarray]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(path)
    except (pa.ArrowInvalid, OSError) as exc:
        raise InputError(path, f"is not a readable Parquet recording ({str(exc).splitlines()[0]})") from None
    return {name: table.column(name).to_numpy(zero_copy_only=False) for name in table.column_names}


def _read_mat(path: Path, variable: str | None) -> dict[str, Any]:
    import scipy.io

    try:
        data = scipy.io.loadmat(path, squeeze_me=True, simplify_cells=True)
    except NotImplementedError:  # MATLAB v7.3 files are HDF5
        data = _read_mat_v73(path, variable)
    except (ValueError, TypeError, OSError) as exc:
        raise InputError(path, f"is not a readable MATLAB file ({str(exc).splitlines()[0]})") from None
    data = {k: v for k, v in data.items() if not k.startswith("__")}
    if variable is None:
        return data
    if variable not in data:
        raise InputError(path, f"has no variable '{variable}' (it has: {', '.join(sorted(data))})",
                         "variable")
    struct = data[variable]
    if not isinstance(struct, dict):
        raise InputError(path, f"variable '{variable}' is not a struct of columns", "variable")
    return struct


def _read_mat_v73(path: Path, variable: str | None) -> dict[str, Any]:
    try:
        import h5py
    except ImportError:
        raise InputError(path, "is a MATLAB v7.3 (HDF5) file, which needs the h5py package "
                         "(pip install h5py); or save it from MATLAB with save(..., '-v7')") from None
    with h5py.File(path, "r") as handle:
        group = handle[variable] if variable is not None and variable in handle else handle
        return {name: np.asarray(item).squeeze() for name, item in group.items()
                if isinstance(item, h5py.Dataset)}


def _raw_columns(path: Path, columns: ColumnMap) -> tuple[str, dict[str, Any]]:
    if not path.is_file():
        raise InputError(path, "recording not found")
    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise InputError(path, f"unknown recording format '{path.suffix}' (allowed: "
                         f"{', '.join(sorted(FORMATS))})")
    if kind == "csv":
        return kind, _read_csv(path)
    if kind == "parquet":
        return kind, _read_parquet(path)
    return kind, _read_mat(path, columns.variable)


def _suggest(name: str, available: list[str]) -> str:
    import difflib

    close = difflib.get_close_matches(name, available, n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


def _column(raw: dict[str, Any], key: str, spec: Column, path: Path, time: np.ndarray | None):
    """One mapped column in SI units, checked: present, numeric, one value per row, no NaN."""
    if spec.column not in raw:
        available = sorted(raw)
        raise InputError(path, f"has no column '{spec.column}' (mapped to {key}{_suggest(spec.column, available)}; "
                         f"it has: {', '.join(available[:20])})", f"{key}.column")
    values = np.asarray(raw[spec.column])
    if values.ndim != 1 or values.dtype.kind not in "fiub":
        raise InputError(path, f"column '{spec.column}' (mapped to {key}) is not one numeric "
                         "value per row", f"{key}.column")
    values = values.astype(np.float64)
    if time is not None and values.size != time.size:
        raise InputError(path, f"column '{spec.column}' has {values.size} rows, time has "
                         f"{time.size}", f"{key}.column")
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        at = f" (time {time[bad[0]]:.9g} s)" if time is not None else ""
        raise InputError(path, f"column '{spec.column}' (mapped to {key}) has {bad.size} missing, "
                         f"NaN or infinite value(s), the first at row {bad[0]}{at}; a recording "
                         "must be complete: cut it to a stretch without them", f"{key}.column")
    return values * UNITS[KIND[key]][spec.unit]


def current_demand(time: np.ndarray, command: np.ndarray, position: np.ndarray,
                   speed: np.ndarray, params: Parameters) -> np.ndarray:
    """The controller's current demand I_ref [A] replayed on recorded signals, at their instants.

    The digital loops run at their own rate on the recorded command, position and
    speed (interpolated onto the controller grid) exactly as in the actuator.
    """
    from ..kernels.control import replay_controller

    rate = params.spec.controller.rate
    grid = np.arange(int(math.ceil(time[-1] * rate - 1e-9)) + 1, dtype=np.float64) / rate
    demand = np.empty(grid.size)
    replay_controller(np.interp(grid, time, command), np.interp(grid, time, position),
                      np.interp(grid, time, speed), params.controller, demand)
    # the demand set at k T holds over the period that follows (ZOH)
    return demand[np.clip(np.floor(time * rate + 1e-9).astype(np.int64), 0, grid.size - 1)]


def read_recording(path: str | Path, columns: ColumnMap, params: Parameters,
                   map_file: str | Path | None = None) -> Trace:
    """A rig recording as a contract trace (module docstring); any problem is an InputError."""
    path = Path(path)
    kind, raw = _raw_columns(path, columns)
    mapped = columns.mapped()
    time = _column(raw, "time", mapped["time"], path, None)
    out = {key: _column(raw, key, spec, path, time) for key, spec in mapped.items() if key != "time"}
    t0 = float(time[0])
    out["time"] = time - t0
    if "current" in out:
        how = "recorded"
    else:
        magnitude = 0.5 * (np.abs(out["current_a"]) + np.abs(out["current_b"]) + np.abs(out["current_c"]))
        if "torque" in out:
            sign, how = np.sign(out["torque"]), "phase currents, signed like the recorded torque"
        else:
            sign = np.sign(current_demand(out["time"], out["command"], out["position"],
                                          out["speed"], params))
            how = "phase currents, signed like the replayed controller's current demand"
        out["current"] = magnitude * sign
    checked = check_columns({k: out[k] for k in COLUMNS if k in out}, path)
    meta = {
        "emaprog_version": __version__,
        "model": "recording",
        "source": {"file": str(path), "format": kind,
                   "sha256": hashlib.sha256(path.read_bytes()).hexdigest()},
        "column_map": columns.model_dump(mode="json"),
        "column_map_file": str(map_file) if map_file is not None else None,
        "time_offset": t0,
        "equivalent_current": how,
        "sample_rate": float(1.0 / np.median(np.diff(checked["time"]))),
        "parameter_file": params.source_file,
    }
    return Trace(checked, meta)
