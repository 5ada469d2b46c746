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
unlike a sign taken from the acceleration), its integrator starting with the current the
unit already held (:func:`integrator_charge`).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)
from scipy.optimize import minimize_scalar
from scipy.stats import median_abs_deviation, trim_mean

from .. import __version__
from ..config.parameters import Parameters
from ..config.yamlfile import load_mapping
from ..errors import InputError, from_validation_error, past_limit
from ..signals import command_start, covering_grid, head_samples
from .dialects import CsvOptions, read_text_table, unit_of
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
KIND = {
    "time": "time",
    "command": "angle",
    "position": "angle",
    "speed": "speed",
    "current": "current",
    "current_a": "current",
    "current_b": "current",
    "current_c": "current",
    "torque": "torque",
    "motor_angle": "angle",
}
PHASE_COLUMNS = ("current_a", "current_b", "current_c")
FORMATS = {
    ".csv": "csv",
    ".txt": "csv",
    ".dat": "csv",
    ".tsv": "csv",
    ".mat": "mat",
    ".parquet": "parquet",
    ".tdms": "tdms",
}
RIG_EXTRA = 'pip install "emaprog[rig]"'


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Column(_Strict):
    """Where one contract column is in the recording, its unit there, and its calibration.

    The value in ``unit`` is ``sign * (scale * raw + offset)``: ``scale`` and ``offset``
    for a logger that records volts or counts (a current probe of 100 mV/A: ``unit: A,
    scale: 10``), ``sign: -1`` for an axis the rig counts the other way.
    """

    column: str = Field(
        min_length=1,
        description="name of the column (CSV header, MATLAB "
        "variable or struct field, Parquet column, "
        "TDMS channel or group/channel)",
    )
    unit: str = Field(description="its unit (UNITS per kind of quantity)")
    scale: float = Field(1.0, allow_inf_nan=False, description="[unit per raw unit] gain")
    offset: float = Field(0.0, allow_inf_nan=False, description="[unit] added after the gain")
    sign: Literal[1, -1] = Field(1, description="-1 inverts the channel")

    @field_validator("scale")
    @classmethod
    def _nonzero(cls, value: float):
        if value == 0.0:
            raise ValueError("scale must not be 0")
        return value


class ColumnMap(_Strict):
    """Contract column -> source column and unit; ``variable``: the MATLAB struct holding them."""

    time: Column
    command: Column | None = None
    position: Column
    speed: Column | None = None
    current: Column | None = None
    current_a: Column | None = None
    current_b: Column | None = None
    current_c: Column | None = None
    torque: Column | None = None
    motor_angle: Column | None = None
    variable: str | None = Field(
        None,
        min_length=1,
        description="MATLAB files: the struct "
        "whose fields are the columns (omitted: top-level variables)",
    )
    csv: CsvOptions = Field(
        CsvOptions(), description="text files: the dialect, where detection is not enough"
    )

    @field_validator(*KIND)
    @classmethod
    def _unit_allowed(cls, value: Column | None, info: ValidationInfo):
        if value is None:
            return value
        allowed = UNITS[KIND[str(info.field_name)]]
        if value.unit not in allowed:
            raise ValueError(
                f"unit '{value.unit}' is not allowed for {info.field_name} "
                f"(allowed: {', '.join(allowed)})"
            )
        return value

    @model_validator(mode="after")
    def _some_current(self):
        phases = [getattr(self, p) is not None for p in PHASE_COLUMNS]
        if self.current is None and not all(phases):
            raise ValueError(
                "map either current (the equivalent current) or all of current_a, "
                "current_b, current_c (it is then computed)"
            )
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
def _read_csv(path: Path, columns: ColumnMap) -> tuple[dict[str, np.ndarray], dict]:
    wanted = [spec.column for spec in columns.mapped().values()]
    return read_text_table(path, wanted, columns.csv)


def _read_tdms(path: Path) -> dict[str, np.ndarray]:
    """An NI TDMS file's channels, by ``group/channel`` and, where unique, by channel name;
    ``waveform_time``: the time track of the first waveform channel (wf_increment)."""
    try:
        from nptdms import TdmsFile
    except ImportError:
        raise InputError(
            path, f"is an NI TDMS file, which needs the npTDMS package ({RIG_EXTRA})"
        ) from None
    try:
        tdms = TdmsFile.read(path)
    except Exception as exc:  # noqa: BLE001 - npTDMS raises many kinds on a bad file
        raise InputError(
            path, f"is not a readable TDMS file ({str(exc).splitlines()[0]})"
        ) from None
    out: dict[str, Any] = {}
    names: dict[str, int] = {}
    for group in tdms.groups():
        for channel in group.channels():
            data = channel[:]
            out[f"{group.name}/{channel.name}"] = data
            names[channel.name] = names.get(channel.name, 0) + 1
            if "waveform_time" not in out and "wf_increment" in channel.properties:
                out["waveform_time"] = channel.time_track()
    for group in tdms.groups():
        for channel in group.channels():
            if names[channel.name] == 1:
                out[channel.name] = out[f"{group.name}/{channel.name}"]
    return out


def _read_parquet(path: Path) -> dict[str, np.ndarray]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(path)
    except (pa.ArrowInvalid, OSError) as exc:
        raise InputError(
            path, f"is not a readable Parquet recording ({str(exc).splitlines()[0]})"
        ) from None
    return {name: table.column(name).to_numpy(zero_copy_only=False) for name in table.column_names}


def _read_mat(path: Path, variable: str | None) -> dict[str, Any]:
    import scipy.io

    try:
        data = scipy.io.loadmat(path, squeeze_me=True, simplify_cells=True)
    except NotImplementedError:  # MATLAB v7.3 files are HDF5
        data = _read_mat_v73(path, variable)
    except (ValueError, TypeError, OSError) as exc:
        raise InputError(
            path, f"is not a readable MATLAB file ({str(exc).splitlines()[0]})"
        ) from None
    data = {k: v for k, v in data.items() if not k.startswith("__")}
    if variable is None:
        return data
    if variable not in data:
        raise InputError(
            path, f"has no variable '{variable}' (it has: {', '.join(sorted(data))})", "variable"
        )
    struct = data[variable]
    if not isinstance(struct, dict):
        raise InputError(path, f"variable '{variable}' is not a struct of columns", "variable")
    return struct


def _read_mat_v73(path: Path, variable: str | None) -> dict[str, Any]:
    try:
        import h5py
    except ImportError:
        raise InputError(
            path,
            "is a MATLAB v7.3 (HDF5) file, which needs the h5py package "
            f"({RIG_EXTRA}); or save it from MATLAB with save(..., '-v7')",
        ) from None
    with h5py.File(path, "r") as handle:
        group = handle[variable] if variable is not None and variable in handle else handle
        return {
            name: np.asarray(item).squeeze()
            for name, item in group.items()
            if isinstance(item, h5py.Dataset)
        }


def _raw_columns(path: Path, columns: ColumnMap) -> tuple[str, dict[str, Any], dict]:
    """The file's columns by name, and what was found about its layout (text files)."""
    if not path.is_file():
        raise InputError(path, "recording not found")
    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise InputError(
            path,
            f"unknown recording format '{path.suffix}' (allowed: {', '.join(sorted(FORMATS))})",
        )
    if kind == "csv":
        raw, layout = _read_csv(path, columns)
        return kind, raw, layout
    if kind == "parquet":
        return kind, _read_parquet(path), {}
    if kind == "tdms":
        return kind, _read_tdms(path), {}
    return kind, _read_mat(path, columns.variable), {}


def _suggest(name: str, available: list[str]) -> str:
    import difflib

    close = difflib.get_close_matches(name, available, n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


def _column(raw: dict[str, Any], key: str, spec: Column, path: Path, time: np.ndarray | None):
    """One mapped column in SI units, checked: present, numeric, one value per row, no NaN."""
    if spec.column not in raw:
        available = sorted(raw)
        raise InputError(
            path,
            f"has no column '{spec.column}' (mapped to {key}{_suggest(spec.column, available)}; "
            f"it has: {', '.join(available[:20])})",
            f"{key}.column",
        )
    values = np.asarray(raw[spec.column])
    if values.ndim != 1 or values.dtype.kind not in "fiub":
        raise InputError(
            path,
            f"column '{spec.column}' (mapped to {key}) is not one numeric value per row",
            f"{key}.column",
        )
    values = values.astype(np.float64)
    if time is not None and values.size != time.size:
        raise InputError(
            path,
            f"column '{spec.column}' has {values.size} rows, time has {time.size}",
            f"{key}.column",
        )
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        at = f" (time {time[bad[0]]:.9g} s)" if time is not None else ""
        raise InputError(
            path,
            f"column '{spec.column}' (mapped to {key}) has {bad.size} missing, "
            f"NaN or infinite value(s), the first at row {bad[0]}{at}; a recording "
            "must be complete: cut it to a stretch without them",
            f"{key}.column",
        )
    values = spec.sign * (spec.scale * values + spec.offset)
    return values * UNITS[KIND[key]][spec.unit]


#: Spellings of units in loggers' unit rows, folded onto the column map's names.
UNIT_SPELLINGS = {
    "sec": "s",
    "msec": "ms",
    "degree": "deg",
    "degrees": "deg",
    "°": "deg",
    "rad/sec": "rad/s",
    "1/min": "rpm",
    "r/min": "rpm",
    "min-1": "rpm",
    "°/s": "deg/s",
    "amp": "A",
    "amps": "A",
    "ma": "mA",
    "nm": "N m",
    "n m": "N m",
    "n.m": "N m",
    "n*m": "N m",
}


def check_unit_row(units_row: dict[str, str], mapped: dict[str, Column], path: Path) -> None:
    """A units row that names another unit of the same kind than the map: refused."""
    for key, spec in mapped.items():
        written = unit_of(units_row.get(spec.column, ""))
        written = UNIT_SPELLINGS.get(written.lower(), UNIT_SPELLINGS.get(written, written))
        allowed = UNITS[KIND[key]]
        match = {u.lower(): u for u in allowed}.get(written.lower()) if written else None
        if match is not None and match != spec.unit and spec.scale == 1.0:
            raise InputError(
                path,
                f"the file's units row says '{units_row[spec.column]}' for "
                f"column '{spec.column}', the column map says '{spec.unit}' (mapped "
                f"to {key}); correct the map's unit",
                f"{key}.unit",
            )


def current_demand(
    time: np.ndarray,
    command: np.ndarray,
    position: np.ndarray,
    speed: np.ndarray,
    params: Parameters,
) -> np.ndarray:
    """The controller's current demand I_ref [A] replayed on recorded signals, at their instants.

    The digital loops run at their own rate on the recorded command, position and
    speed (interpolated onto the controller grid) exactly as in the actuator.
    """
    from ..models.family import family_of

    replay_controller = family_of(params).replay_controller
    rate = params.spec.controller.rate
    grid = covering_grid(float(time[-1]), rate)
    demand = np.empty(grid.size)
    replay_controller(
        np.interp(grid, time, command),
        np.interp(grid, time, position),
        np.interp(grid, time, speed),
        params.controller,
        demand,
    )
    # the demand set at k T holds over the period that follows (ZOH)
    return demand[np.clip(np.floor(time * rate + 1e-9).astype(np.int64), 0, grid.size - 1)]


#: [A] step of the coarse search for :func:`integrator_charge` (then refined by scipy), and
#: the samples it reads at most (a long recording's, evenly thinned).
CHARGE_STEP = 0.05
CHARGE_SAMPLES = 20_000


def integrator_charge(demand: np.ndarray, magnitude: np.ndarray, limit: float) -> float:
    """[A] The current demand the unit's controller already held when the logger started.

    :func:`current_demand` replays the loops from empty integrators, but a unit on the rig
    holds its position under the hinge moment before the test command starts: its speed
    integrator carries the holding current, and the replay, integrating the same recorded
    errors from zero, misses it by that constant for the whole recording (its zero crossings
    move, and the equivalent current is signed wrongly in between). The charge is the
    constant ``c`` in [-``limit``, ``limit``] whose ``|demand + c|`` best matches the phase
    currents' ``magnitude`` (least squares; a grid of :data:`CHARGE_STEP`, then bounded
    Brent). Measured on an independently written actuator simulator held 0.15 s under
    30 N m before its logger started (``benchmarks/independent_unit.py``): 0.82 A found,
    samples signed wrongly 4.4 -> 0.9 % (all where the current is within its noise of 0),
    current energy signed wrongly 8.3e-4 -> 1.1e-5 of the signal (the noise floor of that
    recording's fitness: 7.7e-6).
    """

    def cost(c: float, every: int = 1) -> float:
        return float(np.sum((np.abs(demand[::every] + c) - magnitude[::every]) ** 2))

    grid = np.arange(-limit, limit + CHARGE_STEP / 2, CHARGE_STEP)
    every = max(1, demand.size // CHARGE_SAMPLES)  # the coarse search on a long recording
    best = float(grid[int(np.argmin([cost(c, every) for c in grid]))])
    refined = minimize_scalar(
        cost,
        bounds=(max(best - CHARGE_STEP, -limit), min(best + CHARGE_STEP, limit)),
        method="bounded",
        options={"xatol": 1e-4},
    )
    return float(refined.x) if refined.fun <= cost(best) else best


#: [s] windows of the Savitzky-Golay derivative that makes a speed from an angle: a motor
#: angle (resolver, encoder) is fine enough for the error's own 1 ms; the surface position
#: times the gear ratio carries the position sensor's noise and ADC step times 180, and the
#: replayed controller that signs the equivalent current takes that noise through its speed
#: gain. Measured on the example rig's Reference trace (30 N m, friction 1.5): current
#: energy signed wrongly 0.011 % with 1 ms, 0.002 % with 3 ms (recorded speed: 0.000 %).
SPEED_WINDOW_SECONDS = {"motor_angle": 1e-3, "position": 3e-3}
SPEED_ORDER = 2  # polynomial order of that filter (a centred, lag-free derivative)
#: [-] of the speed limit: a recording whose first millisecond moves the motor faster
#: started in motion (the models start at rest).
AT_REST_SHARE = 0.02


def unwrapped_angle(angle: np.ndarray) -> tuple[np.ndarray, int]:
    """A motor angle [rad] that a resolver or single-turn encoder logs within one turn, made
    continuous, and how many turn boundaries were crossed. At 1 kHz and the fastest motor
    (600 rad/s) a sample moves 0.6 rad, far from the half turn that marks a wrap; an angle
    that never wraps comes back as it is."""
    steps = np.diff(angle)
    crossed = int(np.count_nonzero(np.abs(steps) > math.pi))
    if crossed == 0:
        return angle, 0
    return np.unwrap(angle), crossed


def derived_speed(time: np.ndarray, angle: np.ndarray, source: str = "position") -> np.ndarray:
    """Motor speed [rad/s] from a motor angle [rad] (a motor angle, or the surface position
    times the gear ratio: ``source``): the first derivative of a centred Savitzky-Golay fit
    (order :data:`SPEED_ORDER`) over :data:`SPEED_WINDOW_SECONDS`, at least 5 samples."""
    from scipy.signal import savgol_filter

    period = float(np.median(np.diff(time)))
    window = max(5, int(round(SPEED_WINDOW_SECONDS[source] / period)) | 1)
    window = min(window, angle.size - (1 - angle.size % 2))
    return savgol_filter(angle, window, SPEED_ORDER, deriv=1, delta=period, mode="interp")


def check_at_rest(trace: Trace, params: Parameters, path) -> None:
    """Refuse a recording that starts in motion: both models start at rest at its first
    sample (identification and commissioning; emaprog's own traces always do)."""
    if (trace.metadata or {}).get("model") in ("reference", "monitor"):
        return
    time, speed = trace.time, trace["speed"]
    head = speed[: head_samples(time)]
    limit = AT_REST_SHARE * params.spec.controller.speed_limit
    moving = abs(float(np.mean(head)))
    if moving > limit:
        raise InputError(
            path,
            f"the recording starts in motion (motor speed {moving:.3g} rad/s "
            f"over its first millisecond, above {limit:.3g} rad/s): the models start "
            "at rest, so the first sample must be before the command starts; "
            "trigger the logger before the test command (a pre-roll at rest is "
            "fine) or cut the recording at a moment of rest",
            "speed",
        )


#: [-] share of the conducting samples on which a channel permutation and rotor angle must
#: put both the idle phase and the phase carrying the torque's current where the model's
#: commutation puts them, and its lead over the best distinct hypothesis (another sequence,
#: or a rotor angle 60 degrees electrical or more away), for the recording's channel naming
#: to be trusted (:func:`phase_identity`; chance is 1/6). Measured on the example rig's
#: recordings: 0.92-0.93 with a recorded speed (runner-up 0.33-0.35), 0.70-0.71 with the
#: speed derived from the position (runner-up 0.27).
PHASE_AGREEMENT = 0.6
PHASE_MARGIN = 0.2
#: [deg] resolution of the rotor's electrical angle at the first sample (720 steps a turn,
#: so that the 120 degree shifts that relabel the windings cyclically fall on the grid).
ANGLE_STEP_DEG = 0.5
#: [deg] how far a hypothesis' rotor angle must be from the best one to count as distinct.
DISTINCT_DEG = 60.0


def _identity_scores(
    theta_rel: np.ndarray, currents: np.ndarray, sign: np.ndarray, params: Parameters
) -> tuple[dict[tuple[int, ...], np.ndarray], int]:
    """Agreement of every channel permutation at every rotor angle at the first sample:
    ``{perm: (720,) share of the conducting samples}`` (perm[model winding] = channel)."""
    from itertools import permutations

    from ..models.family import family_of

    magnitude = np.abs(currents).sum(axis=0) / 2.0
    # samples carrying current and a sure torque sign: where the pair conducts, the idle
    # phase is the smallest and the torque's phase the largest along the torque's sign
    conducting = (magnitude > max(0.3 * float(np.median(magnitude)), 1e-9)) & (sign != 0.0)
    count = int(conducting.sum())
    bins = int(round(360.0 / ANGLE_STEP_DEG))
    if count == 0:
        return {perm: np.zeros(bins) for perm in permutations(range(3))}, 0
    idle = np.argmin(np.abs(currents[:, conducting]), axis=0)
    lead = np.argmax(currents[:, conducting] * sign[conducting], axis=0)
    step = 2.0 * math.pi / bins
    where = np.floor(np.mod(theta_rel[conducting], 2.0 * math.pi) / step).astype(np.int64) % bins
    histogram = np.zeros((9, bins))
    np.add.at(histogram, (3 * idle + lead, where), 1.0)
    idle_at, lead_at = family_of(params).commutation_phases((np.arange(bins) + 0.5) * step)
    shifted = (np.arange(bins)[:, None] + np.arange(bins)[None, :]) % bins  # [shift, bin]
    scores = {}
    for perm in permutations(range(3)):
        p = np.asarray(perm)
        code = 3 * p[idle_at] + p[lead_at]  # per angle bin
        scores[perm] = histogram[code[shifted], np.arange(bins)[None, :]].sum(axis=1) / count
    return scores, count


#: [-] the rotor angle is the centroid of the scores within this of their peak (the peak
#: is flat over a few degrees: the idle phase's current decays after each commutation).
#: Measured on seven Reference recordings at 0, 30, 69 and -150 degrees: within 0.7 degrees
#: (the first maximum alone: within 1 degree).
PEAK_DROP = 0.02


def _peak_deg(score: np.ndarray) -> float:
    """The rotor angle [deg] at a score curve's peak (:data:`PEAK_DROP`)."""
    j = int(np.argmax(score))
    near = np.arange(-int(DISTINCT_DEG / ANGLE_STEP_DEG), int(DISTINCT_DEG / ANGLE_STEP_DEG) + 1)
    weight = np.clip(score[(j + near) % score.size] - (score[j] - PEAK_DROP), 0.0, None)
    return float((j + np.sum(weight * near) / np.sum(weight)) * ANGLE_STEP_DEG) % 360.0


def _parity(perm: tuple[int, ...]) -> int:
    return sum(1 for i in range(3) for j in range(i + 1, 3) if perm[i] > perm[j]) % 2


def _circular_deg(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def phase_identity(
    trace_columns: dict[str, np.ndarray],
    params: Parameters,
    channels: dict[str, str],
    torque_sign: np.ndarray,
    expected_deg: float | None = None,
    speed_source: str = "recorded",
) -> dict:
    """Which recorded channel carries which of the model's windings, and the rotor's
    electrical angle at the first sample.

    In each commutation sector of the model (:mod:`~emaprog.kernels.bldc`) one winding is
    idle and one carries the pair current along the torque. The recorded motor angle
    (``motor_angle``, else the integral of the speed) times the pole pairs gives the rotor's
    electrical angle up to its value at the first sample; the smallest recorded phase
    current gives the idle channel and the largest along ``torque_sign`` the torque's. Every
    permutation of the channels is scored at every angle at the first sample
    (:data:`ANGLE_STEP_DEG`): the share of the conducting samples on which both agree.

    A cyclic relabelling of the windings is the same as a rotor 120 degrees electrical on,
    so the scores fix the phase sequence, not which of three cyclic labellings is meant.
    The choice: the labelling whose angle is nearest ``expected_deg`` (the unit's position
    sensor offset found at commissioning, :func:`sensor_offset_deg`); without one, the
    channels as the map names them when their sequence is the model's (the map is taken at
    its word), else - two channels swapped - the swap that puts the rotor nearest electrical
    zero. Returns ``{"windings": {model phase: map key}, "channels": {model phase: logger
    column}, "agreement", "runner_up", "trusted", "electrical_angle_deg", "angle"}``; an
    angle from the position (``speed_source`` ``position``: the speed was derived from it)
    within :func:`twist_tolerance_deg` of 0 is taken as 0.
    """
    pp = params.spec.electrical.pole_pairs
    theta_rel = pp * _angle(trace_columns)
    currents = np.vstack([trace_columns[k] for k in PHASE_COLUMNS])
    scores, _ = _identity_scores(theta_rel, currents, np.sign(torque_sign), params)
    bins = next(iter(scores.values())).size
    best = max(scores, key=lambda q: (float(scores[q].max()), q == (0, 1, 2)))
    top = float(scores[best].max())
    j_best = int(np.argmax(scores[best]))
    angle_of = np.arange(bins) * ANGLE_STEP_DEG
    distance = np.array([_circular_deg(a, angle_of[j_best]) for a in angle_of])
    same = scores[best][distance >= DISTINCT_DEG]
    other = [float(scores[q].max()) for q in scores if _parity(q) != _parity(best)]
    runner = max([float(same.max()) if same.size else 0.0] + other)
    group = [q for q in scores if _parity(q) == _parity(best)]
    candidates = {q: _peak_deg(scores[q]) for q in group}
    if expected_deg is not None:
        chosen = min(group, key=lambda q: _circular_deg(candidates[q], expected_deg))
    elif (0, 1, 2) in group:
        chosen = (0, 1, 2)
    else:
        chosen = min(group, key=lambda q: _circular_deg(candidates[q], 0.0))
    trusted = top >= PHASE_AGREEMENT and top - runner >= PHASE_MARGIN
    keys = {winding: PHASE_COLUMNS[chosen[j]] for j, winding in enumerate("abc")}
    found = (candidates[chosen] + 180.0) % 360.0 - 180.0
    source = (
        "motor_angle"
        if "motor_angle" in trace_columns
        else "integrated speed"
        if speed_source == "recorded"
        else "position"
    )
    tolerance = twist_tolerance_deg(params) if source == "position" else 0.0
    angle = 0.0 if abs(found) <= tolerance else found
    identity = {
        "windings": keys,
        "channels": {w: channels[k] for w, k in keys.items()},
        "agreement": top,
        "runner_up": runner,
        "trusted": bool(trusted),
        "electrical_angle_deg": round(float(angle), 2),
        "angle": source,
    }
    if angle != found:
        identity["note"] = (
            f"rotor angle {found:.1f} deg electrical from the position, within "
            f"the {tolerance:.1f} deg the transmission's twist leaves it: taken as 0"
        )
    return identity


#: [N m] hinge moments a unit meets on the rig (the robustness campaigns span -50 to 70).
RIG_HINGE_MOMENT = 70.0


def twist_tolerance_deg(params: Parameters) -> float:
    """[deg] how far the rotor's electrical angle may be from the surface position times the
    gear ratio: the transmission's twist under :data:`RIG_HINGE_MOMENT`, ``P N H / k``
    (9.6 deg on the shipped set). A recording whose speed is derived from the position
    locates the rotor only to within it (measured on the example unit: 4-8 deg at 20-40 N m)."""
    m = params.spec.mechanical
    return math.degrees(
        params.spec.electrical.pole_pairs
        * m.gear_ratio
        * RIG_HINGE_MOMENT
        / m.transmission_stiffness
    )


def _sensor_electrical_deg(
    trace_columns: dict[str, np.ndarray], params: Parameters, source: str
) -> float:
    """``P`` times the angle sensor's first reading [deg electrical]: the motor angle, or the
    position times the gear ratio (``source``)."""
    reading = (
        float(trace_columns["motor_angle"][0])
        if source == "motor_angle"
        else params.spec.mechanical.gear_ratio * float(trace_columns["position"][0])
    )
    return math.degrees(params.spec.electrical.pole_pairs * reading)


def sensor_offset_deg(
    identity: dict, trace_columns: dict[str, np.ndarray], params: Parameters
) -> tuple[float, str]:
    """The rotor's electrical angle where the angle sensor reads 0 [deg], from a recording's
    identity, and which sensor that is (``motor_angle``, else ``position`` times the gear
    ratio): a property of the unit, stored at commissioning."""
    source = "motor_angle" if "motor_angle" in trace_columns else "position"
    offset = identity["electrical_angle_deg"] - _sensor_electrical_deg(
        trace_columns, params, source
    )
    return round((offset + 180.0) % 360.0 - 180.0, 3), source


def expected_angle_deg(trace_columns: dict[str, np.ndarray], params: Parameters) -> float | None:
    """The rotor's electrical angle at a recording's first sample that the unit's
    commissioning predicts (its stored sensor offset, :func:`sensor_offset_deg`), or None."""
    record = params.spec.commissioning
    if record is None:
        return None
    for r in record.recordings:
        known = r.phase_identity or {}
        if known.get("trusted") and "sensor_offset_deg" in known:
            source = known.get("offset_from", "position")
            if source == "motor_angle" and "motor_angle" not in trace_columns:
                continue
            return float(known["sensor_offset_deg"]) + _sensor_electrical_deg(
                trace_columns, params, source
            )
    return None


#: [-] a sample is read as "one winding idle, two in series" where the smallest recorded
#: phase current is under this share of the largest (commutations, where the winding that
#: left the pair still freewheels, are left out).
IDLE_SHARE = 0.05
#: [-] ... and the largest is at least this share of its 95th percentile over the recording
#: (near zero current the channels' offsets and noise, not their gains, make the ratios).
PAIR_SHARE = 0.2
#: Fewest such samples per winding (idle, for its offset; idle third, for the gain ratio of
#: the two others) for the channels to be balanced.
BALANCE_SAMPLES = 200
#: [-] two channels' gains further apart than this are not a logger's tolerance: a map or
#: wiring mistake.
GAIN_RATIO_LIMIT = 1.2
#: [-] share of the idle samples cut from each tail of an offset's mean.
TRIM = 0.1
#: [standard errors] a gain or offset is corrected only beyond this: on a logger whose
#: channels are right, the estimates' own noise (2-3 mA, 0.03 % on the example unit) is left
#: alone; it moved the example unit's commissioned back-EMF constant by 4 %.
SIGNIFICANT = 3.0
#: [-] standard error of a median over that of a mean, for normal samples (sqrt(pi / 2)).
MEDIAN_EFFICIENCY = math.sqrt(math.pi / 2.0)


def channel_balance(currents: np.ndarray) -> dict:
    """Each phase-current channel's gain and offset from the recording itself (``currents``
    (3, n) as mapped: a, b, c). The windings are in star: where one is idle, the other two
    carry one current in series, ``i_p = -i_q``, whatever the faults (a short circuit
    changes a winding's impedance, not the series law), and the idle one carries none. A
    channel reading ``g i + o`` then shows its offset ``o`` while its winding is idle and
    the gain ratio ``g_p / g_q = -(r_p - o_p) / (r_q - o_q)`` while the two others conduct:
    over the samples of :data:`IDLE_SHARE` and :data:`PAIR_SHARE` (trimmed means of the idle
    readings, medians of the ratios), the three ratios
    solved for the gains in least squares with their geometric mean 1 (the common scale of
    the three is not in the currents; commissioning puts it in ``back_emf_constant``).

    A gain or offset is corrected only where it is :data:`SIGNIFICANT`. Returns ``{"gains":
    {a, b, c}, "offsets": {a, b, c} [A]`` (as corrected: 1 and 0 where not), ``"estimate"``
    (every gain and offset with its standard error), ``"samples": {a, b, c}, "applied"}``;
    ``applied`` is False, with a ``note``, when nothing was significant, a winding was idle on
    fewer than :data:`BALANCE_SAMPLES` samples or two gains are further apart than
    :data:`GAIN_RATIO_LIMIT`.
    """
    magnitude = np.abs(currents)
    order = np.argsort(magnitude, axis=0)
    idle = order[0]
    columns = np.arange(currents.shape[1])
    largest = magnitude[order[2], columns]
    scale = float(np.percentile(largest, 95)) if largest.size else 0.0
    quiet = (magnitude[idle, columns] < IDLE_SHARE * largest) & (largest > PAIR_SHARE * scale)
    counts = [int(np.count_nonzero(quiet & (idle == x))) for x in range(3)]
    names = tuple("abc")
    result: dict[str, Any] = {"samples": dict(zip(names, counts))}
    if min(counts) < BALANCE_SAMPLES:
        result.update(
            gains=dict.fromkeys(names, 1.0),
            offsets=dict.fromkeys(names, 0.0),
            applied=False,
            note=f"a winding idle on fewer than {BALANCE_SAMPLES} samples with the two "
            "others conducting: channels taken as recorded",
        )
        return result
    # the idle channel's mean, its tails trimmed (a mean, not a median: an ADC's steps are
    # often coarser than an offset, and its noise spreads them out only on average)
    idle_readings = [currents[x, quiet & (idle == x)] for x in range(3)]
    offsets = np.array([float(trim_mean(r, TRIM)) for r in idle_readings])
    offset_errors = np.array(
        [float(median_abs_deviation(r, scale="normal")) / math.sqrt(r.size) for r in idle_readings]
    )
    centred = currents - offsets[:, None]
    # log g_p - log g_q = log(ratio) for each idle third; rows (a-b | c idle), (b-c | a), (c-a | b)
    system = np.array([[1.0, -1.0, 0.0], [0.0, 1.0, -1.0], [-1.0, 0.0, 1.0], [1.0, 1.0, 1.0]])
    logs, log_errors = [], []
    for p, q, third in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        on = quiet & (idle == third)
        ratios = np.log(np.abs(centred[p, on] / centred[q, on]))
        logs.append(float(np.median(ratios)))
        log_errors.append(
            MEDIAN_EFFICIENCY
            * float(median_abs_deviation(ratios, scale="normal"))
            / math.sqrt(ratios.size)
        )
    solve = np.linalg.pinv(system)[:, :3]
    log_gains = solve @ np.array(logs)
    gain_errors = np.sqrt(np.diag(solve @ np.diag(np.square(log_errors)) @ solve.T))
    gains = np.exp(log_gains)
    # each correction only where it is significant: a channel read right is left as read
    use_offset = np.abs(offsets) > SIGNIFICANT * offset_errors
    use_gain = np.abs(log_gains) > SIGNIFICANT * gain_errors
    plausible = bool(gains.max() / gains.min() <= GAIN_RATIO_LIMIT)
    result.update(
        gains={n: round(float(g), 6) if u else 1.0 for n, g, u in zip(names, gains, use_gain)},
        offsets={
            n: round(float(o), 6) if u else 0.0 for n, o, u in zip(names, offsets, use_offset)
        },
        estimate={
            "gains": {n: round(float(g), 6) for n, g in zip(names, gains)},
            "gain_errors": {n: round(float(e), 6) for n, e in zip(names, gain_errors * gains)},
            "offsets": {n: round(float(o), 6) for n, o in zip(names, offsets)},
            "offset_errors": {n: round(float(e), 6) for n, e in zip(names, offset_errors)},
        },
        applied=plausible and bool(np.any(use_offset) or np.any(use_gain)),
    )
    if not plausible:
        result.update(gains=dict.fromkeys(names, 1.0), offsets=dict.fromkeys(names, 0.0))
        result["note"] = (
            f"two channels' gains over {GAIN_RATIO_LIMIT:g} times apart: channels taken as "
            "recorded (a scale or wiring mistake in the map?)"
        )
    elif not result["applied"]:
        result["note"] = (
            f"no gain or offset beyond {SIGNIFICANT:g} standard errors: channels taken as recorded"
        )
    return result


#: Ratios of a recorded channel to what the other channels say it should be, and the
#: mapping mistake each one points to (:func:`check_plausible`).
_SUSPECTS = (
    (60.0 / (2.0 * math.pi), "rpm mapped as rad/s?"),
    (2.0 * math.pi / 60.0, "rad/s mapped as rpm?"),
    (180.0 / math.pi, "deg/s mapped as rad/s?"),
    (math.pi / 180.0, "rad/s mapped as deg/s?"),
    (6.0, "rpm mapped as deg/s?"),
    (1.0 / 6.0, "deg/s mapped as rpm?"),
    (-1.0, "the sign is inverted (sign: -1)?"),
)
#: [-] how far a channel may be from what the others say before the map is suspected.
PLAUSIBLE_RATIO = 0.3
#: [rad] motor travel (position times gear ratio) over which the motor angle is compared with
#: it: what the two differ by is the transmission's twist and the backlash, on the shipped
#: set 0.06 rad of motor at a 100 N m hinge moment and 0.18 rad for the whole backlash range
#: (1e-3 rad of surface).
MOTOR_TRAVEL_CLEAR = 1.0
#: What a motor angle off the position times the gear points to when no unit mistake does.
ANGLE_OTHERWISE = "a unit, scale or sign in the map, or the set's gear_ratio, is wrong?"


#: The same for a motor angle against the position times the gear ratio.
_ANGLE_SUSPECTS = (
    (180.0 / math.pi, "deg mapped as rad?"),
    (math.pi / 180.0, "rad mapped as deg?"),
    (-1.0, "the sign is inverted (sign: -1)?"),
)


def _suspect(
    ratio: float,
    suspects=_SUSPECTS,
    otherwise: str = "a unit, scale or sign in the map is wrong?",
) -> str:
    best = min(
        suspects,
        key=lambda s: (
            abs(math.log(abs(ratio) / abs(s[0])))
            + (0.0 if math.copysign(1.0, ratio) == math.copysign(1.0, s[0]) else 10.0)
        ),
    )
    close = abs(ratio / best[0] - 1.0) < PLAUSIBLE_RATIO
    return best[1] if close else otherwise


def speed_source_of(trace: Trace) -> str:
    """Where a trace's speed comes from: ``recorded``, ``motor_angle`` or ``position``."""
    speed = (trace.metadata or {}).get("speed")
    return speed.get("source", "recorded") if isinstance(speed, dict) else "recorded"


#: [-] RMS of ``|replayed demand + charge| - (|I_A| + |I_B| + |I_C|)/2`` over the RMS of the
#: latter beyond which the set's controller is not the unit's: its demand cannot sign the
#: equivalent current (:func:`check_plausible`). Measured on units of an independently
#: written simulator (``benchmarks/independent_unit.py``): 0.047-0.055 on 24 recordings with
#: the set's gains (0.053-0.057 on the example rig's), 0.36 with the speed loop's gains
#: x0.7 (signs still right: 0.2 % wrong where the current clears its noise), 1.7-2.1 with
#: the position gain x0.8 or x1.2 (36-47 % wrong).
DEMAND_MISFIT_LIMIT = 1.0
#: [-] ... checked where the current's RMS is at least this many times the set's
#: current-line noise (a recording at rest has nothing to sign).
DEMAND_CLEAR_OF_NOISE = 5.0


def check_plausible(trace: Trace, params: Parameters, path) -> None:
    """Before fitting: the mapped channels agree with each other and with the parameter set.

    The position against the command it follows, the recorded motor speed against the
    derivative of the motor angle (or of the surface position times the gear ratio), the
    current's peak against the drive's current limit, and the controller's current demand
    replayed on the recording (which signs an equivalent current built from the phases)
    against the phase currents; the channel most likely mis-mapped, or the set's
    ``controller``, is named with the evidence (exit 2). Only for rig recordings (read
    through a column map).
    """
    meta = trace.metadata or {}
    if meta.get("model") != "recording" or not meta.get("column_map"):
        return
    out = trace.columns
    speed_source = speed_source_of(trace)
    mapped = {
        k: Column.model_validate(v)
        for k, v in meta["column_map"].items()
        if k in KIND and v is not None
    }
    limit = params.spec.controller.speed_limit
    gear = params.spec.mechanical.gear_ratio
    time = out["time"]
    command, position = out["command"], out["position"]
    if float(np.ptp(command)) > 0 and float(np.ptp(position)) > 0:
        c, q = command - command.mean(), position - position.mean()
        ratio = float(np.dot(q, c) / max(np.dot(c, c), 1e-300))
        if ratio < 0 or not 0.1 < ratio < 10.0:
            key = "position"
            raise InputError(
                path,
                f"position is {ratio:.3g} x the command it follows: "
                f"{'the sign of position or command is inverted (sign: -1)?' if ratio < 0 else 'a unit or scale of position or command is wrong (deg, rad, mrad)?'}"
                f" (column '{mapped[key].column}')",
                key,
            )
    if "motor_angle" in out and float(np.ptp(position)) > 0:
        # the Monitor commutates on it: its travel must be the position's times the gear
        a, q = out["motor_angle"] - out["motor_angle"].mean(), gear * (position - position.mean())
        ratio = float(np.dot(a, q) / max(np.dot(q, q), 1e-300))
        if float(np.ptp(q)) > MOTOR_TRAVEL_CLEAR and abs(ratio - 1.0) > PLAUSIBLE_RATIO:
            raise InputError(
                path,
                f"motor_angle is {ratio:.3g} x position x gear ratio {gear:g}: "
                f"{_suspect(ratio, _ANGLE_SUSPECTS, ANGLE_OTHERWISE)} (column '{mapped['motor_angle'].column}')",
                "motor_angle",
            )
    if speed_source == "recorded" and time.size > 20:
        angle = out["motor_angle"] if "motor_angle" in out else gear * out["position"]
        derived = derived_speed(time, angle, "motor_angle" if "motor_angle" in out else "position")
        if float(np.sqrt(np.mean(derived**2))) > 0.02 * limit:
            ratio = float(np.dot(out["speed"], derived) / np.dot(derived, derived))
            if abs(ratio - 1.0) > PLAUSIBLE_RATIO:
                source = (
                    "motor_angle" if "motor_angle" in out else f"position x gear ratio {gear:g}"
                )
                raise InputError(
                    path,
                    f"speed is {ratio:.3g} x d({source})/dt: "
                    f"{_suspect(ratio)} (column '{mapped['speed'].column}')",
                    "speed",
                )
    current_limit = params.spec.electrical.current_limit
    keys = [k for k in ("current", *PHASE_COLUMNS) if k in mapped and k in out]
    peak = max(float(np.max(np.abs(out[k]))) for k in keys)
    if peak > 3.0 * current_limit:
        raise InputError(
            path,
            f"the current reaches {peak:.4g} A, over 3 x the drive's "
            f"{current_limit:g} A limit: mA mapped as A? (column "
            f"'{mapped[keys[0]].column}')",
            f"{keys[0]}.unit",
        )
    misfit = meta.get("demand_misfit")
    noise = params.spec.sensors.current_noise
    clear = float(np.sqrt(np.mean(out["current"] ** 2))) >= DEMAND_CLEAR_OF_NOISE * noise
    if misfit is not None and misfit > DEMAND_MISFIT_LIMIT and clear:
        raise InputError(
            path,
            "the current demand of the parameter set's controller, replayed on the "
            "recorded command, position and speed, misses the phase currents' magnitude by "
            f"{past_limit(misfit, DEMAND_MISFIT_LIMIT, '.0%')} of its RMS (at most "
            f"{DEMAND_MISFIT_LIMIT:.0%}), so it cannot sign the equivalent current: the "
            "set's controller gains are not this unit's (position_gain, speed_gain, "
            "speed_integral in the parameter set), or the command, position or speed "
            "channel is wrong; give the unit's gains, or map its torque or equivalent "
            "current",
            "controller",
        )


def _angle(out: dict[str, np.ndarray]) -> np.ndarray:
    """The motor angle from the first sample [rad]: recorded, else the integrated speed."""
    if "motor_angle" in out:
        return out["motor_angle"] - out["motor_angle"][0]
    time, speed = out["time"], out["speed"]
    return np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(time))])


#: ``command_of(time, position) -> (command, note)``: the test command at the recorded
#: instants when the recording has no command channel (``models.alignment``).
CommandOf = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, str]]


def read_recording(
    path: str | Path,
    columns: ColumnMap,
    params: Parameters,
    map_file: str | Path | None = None,
    command_of: CommandOf | None = None,
) -> Trace:
    """A rig recording as a contract trace (module docstring); any problem is an InputError.

    Without a mapped ``command``, ``command_of`` supplies it (a scenario's test command
    placed by the response); without either the recording is refused."""
    path = Path(path)
    kind, raw, layout = _raw_columns(path, columns)
    mapped = columns.mapped()
    if layout.get("units_row"):
        check_unit_row(layout["units_row"], mapped, path)
    if "command" not in mapped and command_of is None:
        raise InputError(
            map_file or path,
            "maps no command and no test command was given: map "
            "the logger's command channel, or give the test command as a scenario "
            "with --scenario (it is then placed in time by the response)",
            "command",
        )
    time = _column(raw, "time", mapped["time"], path, None)
    out = {
        key: _column(raw, key, spec, path, time) for key, spec in mapped.items() if key != "time"
    }
    t0 = float(time[0])
    out["time"] = time - t0
    turns = 0
    if "motor_angle" in out:
        out["motor_angle"], turns = unwrapped_angle(out["motor_angle"])
    command_note = "recorded"
    if "command" not in out:
        assert command_of is not None  # refused above without one
        out["command"], command_note = command_of(out["time"], out["position"])
    if "speed" in out:
        speed = {"source": "recorded", "note": "recorded"}
    else:
        source = "motor_angle" if "motor_angle" in out else "position"
        gear = params.spec.mechanical.gear_ratio
        angle = out["motor_angle"] if source == "motor_angle" else gear * out["position"]
        out["speed"] = derived_speed(out["time"], angle, source)
        speed = {
            "source": source,
            "note": (
                (
                    "derived from motor_angle"
                    if source == "motor_angle"
                    else f"derived from position x gear ratio {gear:g}"
                )
                + f" (Savitzky-Golay derivative, order {SPEED_ORDER}, "
                f"{SPEED_WINDOW_SECONDS[source] * 1e3:g} ms window)"
            ),
        }
    phases = all(k in out for k in PHASE_COLUMNS)
    balance = None
    if phases and "current" not in out:
        balance = channel_balance(np.vstack([out[k] for k in PHASE_COLUMNS]))
        if balance["applied"]:
            for k, x in zip(PHASE_COLUMNS, "abc"):
                out[k] = (out[k] - balance["offsets"][x]) / balance["gains"][x]
    charge = misfit = None
    if "current" in out:
        how, sign = "recorded", np.sign(out["current"])
    else:
        magnitude = 0.5 * (
            np.abs(out["current_a"]) + np.abs(out["current_b"]) + np.abs(out["current_c"])
        )
        if "torque" in out:
            how = "phase currents, signed like the recorded torque"
            sign = np.sign(out["torque"])
        else:
            # the replayed controller's demand (module docstring). Signing by the commutation
            # sector instead was measured: fewer wrong signs against the true torque (0.18 %
            # of the samples against 0.42 %), but the healthy Monitor, whose own current
            # follows the same demand, then fitted the example unit's pre-roll recordings
            # worse (k_e x0.939 against x0.980, true 0.98)
            demand = current_demand(
                out["time"], out["command"], out["position"], out["speed"], params
            )
            charge = integrator_charge(demand, magnitude, params.spec.electrical.current_limit)
            misfit = float(
                np.sqrt(np.mean((np.abs(demand + charge) - magnitude) ** 2))
                / max(float(np.sqrt(np.mean(magnitude**2))), 1e-300)
            )
            how = (
                "phase currents, signed like the replayed controller's current demand (its "
                f"integrator holding {charge:.3f} A at the first sample, fitted to the phase "
                "currents' magnitude)"
            )
            sign = np.sign(demand + charge)
    identity = None
    if phases:
        identity = phase_identity(
            out,
            params,
            {k: mapped[k].column for k in PHASE_COLUMNS},
            sign,
            expected_angle_deg(out, params),
            speed["source"],
        )
        identity["sensor_offset_deg"], identity["offset_from"] = sensor_offset_deg(
            identity, out, params
        )
    if "current" not in out:
        out["current"] = magnitude * sign
    checked = check_columns({k: out[k] for k in COLUMNS if k in out}, path)
    meta = {
        "emaprog_version": __version__,
        "model": "recording",
        "source": {
            "file": str(path.resolve()),
            "format": kind,
            "sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
            **({"layout": layout["dialect"]} if "dialect" in layout else {}),
        },
        "column_map": columns.model_dump(mode="json"),
        "column_map_file": str(Path(map_file).resolve()) if map_file is not None else None,
        "time_offset": t0,
        "equivalent_current": how,
        **({"integrator_charge": charge, "demand_misfit": misfit} if charge is not None else {}),
        "speed": speed,
        "command": command_note,
        **({"motor_angle": f"unwrapped: {turns} turn boundaries crossed"} if turns else {}),
        "command_start": command_start(checked["time"], checked["command"]),
        "sample_rate": float(1.0 / np.median(np.diff(checked["time"]))),
        "parameter_file": params.source_file,
    }
    if identity is not None:
        meta["phase_identity"] = identity
    if balance is not None:
        meta["current_channels"] = balance
    return Trace(checked, meta)
