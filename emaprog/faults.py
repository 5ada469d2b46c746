"""THE fault catalogue: every fault's name, quantities, units, ranges, labels and severity.

Every other module iterates over :data:`CATALOGUE` (or :data:`FAULTS`,
:data:`QUANTITIES`) instead of naming faults: the scenario and campaign schemas,
the identification genes, the case table columns, the summaries, the history
table and the report tables. A fault has one of three *layouts*, which decide
the shape of its YAML value, of its campaign distribution and of its growth law:

* ``scalar`` -- one number (``friction: 1.8``);
* ``per_phase`` -- one fraction per motor phase (``short_circuit: {a: 0.2}``),
  campaign distribution ``{phase: any|a|b|c, fraction: {uniform: [lo, hi]}}``;
* ``polar`` -- a magnitude and an angle (``eccentricity: {zeta: 0.2, phase: 0}``),
  campaign distribution ``{zeta: {uniform: ..}, phase: {uniform: ..}}``.

Eccentricity has two magnitudes: the air-gap reduction zeta [-] (the physical
fault, the Reference Model's and every user-facing value) and the Monitor's
shape-function amplitude Z = c zeta. They are separate fields of separate
kernel structs (:class:`FaultParams`, :class:`MonitorFaults`) and converted in
one place, :func:`monitor_form`.
"""

from __future__ import annotations

import json
import math
from importlib import resources
from typing import Any, Literal, NamedTuple

import numpy as np

from .kernels.structs import FaultParams, MonitorFaults

__all__ = [
    "CATALOGUE",
    "FAULTS",
    "FAULT_NAMES",
    "HEALTHY",
    "PHASES",
    "PHASE_FAULTS",
    "QUANTITIES",
    "Fault",
    "ModelError",
    "FaultParams",
    "MonitorFaults",
    "Quantity",
    "fault_load",
    "flatten",
    "healthy_values",
    "monitor_form",
    "nested",
    "reference_form",
    "severity",
    "values_of",
    "worst_phase",
]

TWO_PI = 2.0 * math.pi
Layout = Literal["scalar", "per_phase", "polar"]


class Quantity(NamedTuple):
    """One scalar fault quantity (a column stem of the case table, docs/reference.md, Campaign results)."""

    name: str  # e.g. "short_circuit_a"
    key: (
        str | None
    )  # key inside the fault's YAML mapping ("a", "zeta"); None: the fault is a number
    unit: str
    healthy: float
    lower: float  # allowed true values [lower, upper] (upper excluded when upper_open)
    upper: float
    upper_open: bool
    label: str  # for tables and figures
    measure: Literal["absolute", "relative"]  # how its identification error is measured
    tolerance: float | None  # tolerance bar on |error| in that measure; None: no bar
    circular: bool  # an angle: wraps around, errors wrapped into (-pi, pi]


class ModelError(NamedTuple):
    """A quantity's standard error beyond the noise:
    ``sqrt((factor sigma)^2 + (share d)^2 + (load L)^2)``, ``sigma`` the linearised standard
    error from the fit's residual, ``d`` the estimate's deviation from healthy, ``L`` the
    recording's :func:`fault_load`. ``factor`` [-] widens what the residual shows; ``share``
    [-] is a relative error of the Monitor's own fault signature (the signature errors of docs/reference.md, The models
    are relative: the larger the fault, the larger the part of the error no residual noise
    explains); ``load`` [the quantity's unit] is what the other faults' signature errors
    leave on this quantity per unit of fault load (measured on the twins: a healthy phase's
    shorted-fraction estimate is pulled up only when the rotor is eccentric, 0.0007 at the
    median and 0.013 at worst on phase C; a small friction fault's error is as large as a
    big one's when other faults are present)."""

    factor: float
    share: float = 0.0
    load: float = 0.0


#: The model-error laws and the ratios they were calibrated under, as
#: ``benchmarks/interval_factors.py --write`` left them (``emaprog/data/model_errors.json``,
#: with their provenance): laws are measured, never typed in.
MODEL_ERRORS: dict[str, Any] = json.loads(
    resources.files("emaprog").joinpath("data", "model_errors.json").read_text()
)


def _laws(basis: str, *quantities: str) -> tuple[ModelError, ...]:
    """The :class:`ModelError` of each quantity on a basis of :data:`MODEL_ERRORS`."""
    return tuple(ModelError(*MODEL_ERRORS["laws"][basis][q]) for q in quantities)


class Fault(NamedTuple):
    name: str
    label: str
    layout: Layout
    quantities: tuple[Quantity, ...]
    severity: str  # what the health thresholds apply to (the parameter set's health:), with unit
    default_bounds: tuple[float, float]  # identification search range of its magnitudes
    bound_limits: tuple[float, float]  # what a search bound itself may be
    #: 1 sigma of one identification's severity error (trend's RUL bootstrap never assumes
    #: better), kept conservative: the 95th percentile of |error| over 1.96 on the 50-case
    #: quick campaign before the pair eccentricity law (friction 2.5 % of k_f ~ 1.5,
    #: backlash 3.7e-5 rad, shorted fraction 0.04, zeta 0.11). Today's p95 are 2-5 times
    #: smaller (docs/sweep/quick) but the tails are not (largest shorted fraction error 0.07).
    identification_sigma: float
    #: How much wider than its linearised standard error each quantity's error really is,
    #: one :class:`ModelError` per quantity in ``quantities`` order, for a unit's own
    #: parameter set (commissioned, or the shipped one): the Monitor's deterministic
    #: mismatch with the three-phase motor and the baseline's own error, which the
    #: residual's noise does not show. Calibrated with ``benchmarks/interval_factors.py`` on
    #: ``campaigns/calibration-units.yaml`` (400 commissioned spread units), kept apart from
    #: the robustness campaign on which the intervals are then checked.
    model_error: tuple[ModelError, ...]
    #: The same for a twin experiment (a trace of emaprog's Reference Model identified with
    #: the very values that produced it: only the Monitor's mismatch is left), calibrated on
    #: ``campaigns/calibration-twins.yaml`` (400 cases) and checked on the quick campaign.
    #: Every factor is at least 1: the linearised error is the noise's own, and factors
    #: under 1 (fitted before, down to 0.2 where the mismatch dwarfed the noise) left twins
    #: with five times the noise covered in 65-82 % of cases (campaigns/off-calibration).
    #: The phases' laws differ: the Monitor's mismatch is not the same on each winding.
    twin_error: tuple[ModelError, ...]
    #: (incipient, degraded, failure) severities a parameter set's ``health:`` section takes
    #: when it leaves the fault out (a unit file written before the fault was catalogued):
    #: the shipped set's own thresholds.
    health: tuple[float, float, float]

    @property
    def magnitudes(self) -> tuple[Quantity, ...]:
        """The quantities whose deviation from healthy is the fault's severity (not angles)."""
        return tuple(q for q in self.quantities if not q.circular)


def _phase(x: str) -> Quantity:
    return Quantity(
        f"short_circuit_{x}",
        x,
        "-",
        0.0,
        0.0,
        1.0,
        True,
        f"short circuit {x.upper()}",
        "absolute",
        0.03,
        False,
    )


CATALOGUE: tuple[Fault, ...] = (
    Fault(
        "friction",
        "dry-friction increase",
        "scalar",
        (
            Quantity(
                "friction",
                None,
                "-",
                1.0,
                0.1,
                10.0,
                False,
                "friction multiplier",
                "relative",
                0.05,
                False,
            ),
        ),
        "friction |k_f - 1| [-]",
        (0.5, 4.0),
        (0.1, 10.0),
        0.019,
        _laws("unit", "friction"),
        _laws("twin", "friction"),
        (0.15, 0.6, 1.5),
    ),
    Fault(
        "backlash",
        "backlash",
        "scalar",
        (
            Quantity(
                "backlash", None, "rad", 0.0, 0.0, 0.01, False, "backlash", "absolute", 5e-5, False
            ),
        ),
        "backlash, total play [rad]",
        (0.0, 1.5e-3),
        (0.0, 0.01),
        1.9e-5,
        _laws("unit", "backlash"),
        _laws("twin", "backlash"),
        (1.0e-4, 5.0e-4, 1.0e-3),
    ),
    Fault(
        "short_circuit",
        "phase short circuit",
        "per_phase",
        tuple(_phase(x) for x in "abc"),
        "short circuit, worst phase [-]",
        (0.0, 0.5),
        (0.0, 0.95),
        0.02,
        _laws("unit", "short_circuit_a", "short_circuit_b", "short_circuit_c"),
        _laws("twin", "short_circuit_a", "short_circuit_b", "short_circuit_c"),
        (0.05, 0.2, 0.35),
    ),
    Fault(
        "eccentricity",
        "rotor static eccentricity",
        "polar",
        (
            Quantity(
                "eccentricity_zeta",
                "zeta",
                "-",
                0.0,
                0.0,
                1.0,
                True,
                "eccentricity zeta",
                "absolute",
                0.05,
                False,
            ),
            Quantity(
                "eccentricity_phase",
                "phase",
                "rad",
                0.0,
                0.0,
                TWO_PI,
                False,
                "eccentricity phase",
                "absolute",
                None,
                True,
            ),
        ),
        "eccentricity zeta [-]",
        (0.0, 0.8),
        (0.0, 0.95),
        0.055,
        _laws("unit", "eccentricity_zeta", "eccentricity_phase"),
        _laws("twin", "eccentricity_zeta", "eccentricity_phase"),
        (0.08, 0.3, 0.5),
    ),
)

FAULTS: dict[str, Fault] = {f.name: f for f in CATALOGUE}
FAULT_NAMES: tuple[str, ...] = tuple(FAULTS)
#: Every scalar quantity, in kernel (FaultParams) order.
QUANTITIES: dict[str, Quantity] = {q.name: q for f in CATALOGUE for q in f.quantities}
PHASES = "abc"
#: The faults that sit on one motor phase: for each, which phase is reported too.
PHASE_FAULTS: tuple[str, ...] = tuple(f.name for f in CATALOGUE if f.layout == "per_phase")


class Nuisance(NamedTuple):
    """An operating condition estimated beside the faults, never a verdict."""

    name: str
    label: str
    unit: str
    default: float  # its value when not estimated
    bounds: tuple[float, float]  # default search range (``identify.nuisance_bounds``)
    limits: tuple[float, float]  # what a search bound itself may be
    fmt: str  # how the terminal and report.md print it
    load_scale: (
        float  # [its unit] the model-error law's load scale (benchmarks/interval_factors.py)
    )
    description: str


#: The nuisances, in gene order: one table for the schema, the genes, the unit rows, the
#: report and the calibration.
NUISANCES: dict[str, Nuisance] = {
    n.name: n
    for n in (
        Nuisance(
            "hinge_moment",
            "hinge moment",
            "N m",
            0.0,
            (-500.0, 500.0),
            (-5000.0, 5000.0),
            "{:.1f}",
            5.0,
            "constant hinge moment",
        ),
        Nuisance(
            "resistance_factor",
            "winding resistance factor",
            "-",
            1.0,
            (0.8, 1.3),
            (0.5, 2.0),
            "{:.3f}",
            0.05,
            "winding resistance over the set's (temperature)",
        ),
        Nuisance(
            "hinge_stiffness",
            "aerodynamic spring",
            "N m/rad",
            0.0,
            (0.0, 5000.0),
            (-1.0e4, 1.0e5),
            "{:.0f}",
            200.0,
            "hinge moment per rad of surface deflection (an aerodynamic spring), beside the "
            "constant hinge moment",
        ),
    )
}

NUISANCE_NAMES: tuple[str, ...] = tuple(NUISANCES)

#: The kernels' field of each catalogue quantity (:class:`FaultParams`; :class:`MonitorFaults`
#: holds Z = c zeta in ``eccentricity_z``). The kernels read fault rows by position, so the
#: structs must list these fields in the catalogue's order: :func:`check_kernel_order`.
KERNEL_FIELD = {
    "friction": "friction",
    "backlash": "backlash",
    "short_circuit_a": "short_a",
    "short_circuit_b": "short_b",
    "short_circuit_c": "short_c",
    "eccentricity_zeta": "eccentricity_zeta",
    "eccentricity_phase": "eccentricity_phase",
}
MONITOR_FIELD = {**KERNEL_FIELD, "eccentricity_zeta": "eccentricity_z"}


def check_kernel_order(reference: tuple[str, ...], monitor: tuple[str, ...]) -> None:
    """Refuse (at import) kernel fault structs whose fields are not the catalogue's
    quantities in the catalogue's order: a fault added to one but not the other, or in
    another place, would be read as a different fault."""
    for struct, fields, names in (
        ("FaultParams", reference, KERNEL_FIELD),
        ("MonitorFaults", monitor, MONITOR_FIELD),
    ):
        expected = tuple(names.get(q, f"<no kernel field for {q}>") for q in QUANTITIES)
        if tuple(fields) != expected:
            raise ImportError(
                f"emaprog.kernels.structs.{struct} has the fields {tuple(fields)}; "
                f"the fault catalogue needs {expected} in this order"
            )


check_kernel_order(FaultParams._fields, MonitorFaults._fields)

HEALTHY = FaultParams(*(q.healthy for q in QUANTITIES.values()))


def healthy_values() -> dict[str, float]:
    """Every quantity at its healthy value."""
    return {name: q.healthy for name, q in QUANTITIES.items()}


def flatten(faults) -> dict[str, float]:
    """Scalar quantities of a scenario's ``faults`` model, keyed as :data:`QUANTITIES`."""
    out = {}
    for fault in CATALOGUE:
        value = getattr(faults, fault.name)
        for q in fault.quantities:
            out[q.name] = float(value if q.key is None else getattr(value, q.key))
    return out


def uniform_value(dist, u: float, healthy_value: float) -> float:
    """``u`` in [0, 1) on a ``{uniform: [lo, hi]}`` distribution; the healthy value without one."""
    if dist is None:
        return healthy_value
    lo, hi = dist.uniform
    return float(lo + u * (hi - lo))


class ScalarLayout:
    """One number (``friction: 1.8``): one campaign draw, grows by the severity itself."""

    name = "scalar"

    def draw(self, rng: np.random.Generator) -> tuple:
        return (rng.random(),)

    def sampled(self, fault: Fault, dist, draws: tuple) -> Any:
        return uniform_value(dist, draws[0], fault.quantities[0].healthy)

    def grown(self, fault: Fault, level: float, growth, limit: float) -> Any:
        (q,) = fault.quantities
        return min(q.healthy + level, q.upper)

    def nested(self, fault: Fault, values: dict[str, float]) -> Any:
        return values[fault.quantities[0].name]


class PerPhaseLayout:
    """One fraction per motor phase (``short_circuit: {a: 0.2}``): a phase and a fraction are
    drawn; the growth law raises its phase's fraction."""

    name = "per_phase"

    def draw(self, rng: np.random.Generator) -> tuple:
        return int(rng.integers(3)), rng.random()  # phase, fraction

    def sampled(self, fault: Fault, dist, draws: tuple) -> Any:
        value = {q.key: q.healthy for q in fault.quantities}
        if dist is not None:
            phase = PHASES[draws[0]] if dist.phase == "any" else dist.phase
            value[phase] = uniform_value(dist.fraction, draws[1], 0.0)
        return value

    def grown(self, fault: Fault, level: float, growth, limit: float) -> Any:
        value = {q.key: q.healthy for q in fault.quantities}
        if growth is not None:
            value[growth.phase] = min(level, limit)
        return value

    def nested(self, fault: Fault, values: dict[str, float]) -> Any:
        return {q.key: values[q.name] for q in fault.quantities}


class PolarLayout(PerPhaseLayout):
    """A magnitude and an angle (``eccentricity: {zeta: 0.2, phase: 0}``): both drawn; the
    growth law raises the magnitude at its angle."""

    name = "polar"

    def draw(self, rng: np.random.Generator) -> tuple:
        return rng.random(), rng.random()  # magnitude, angle

    def sampled(self, fault: Fault, dist, draws: tuple) -> Any:
        magnitude, angle = fault.quantities
        if dist is None:
            return {q.key: q.healthy for q in fault.quantities}
        return {
            magnitude.key: uniform_value(dist.zeta, draws[0], magnitude.healthy),
            angle.key: uniform_value(dist.phase, draws[1], angle.healthy),
        }

    def grown(self, fault: Fault, level: float, growth, limit: float) -> Any:
        magnitude, angle = fault.quantities
        if growth is None:
            return {q.key: q.healthy for q in fault.quantities}
        return {magnitude.key: min(level, limit), angle.key: growth.angle}


#: Each layout's behaviour: campaign draws, sampled and grown values, the report's shape.
LAYOUTS: dict[str, ScalarLayout | PerPhaseLayout | PolarLayout] = {
    "scalar": ScalarLayout(),
    "per_phase": PerPhaseLayout(),
    "polar": PolarLayout(),
}


def nested(values: dict[str, Any]) -> dict:
    """The report's shape (docs/reference.md, Identification report) (``{"short_circuit": {"a": ..}, ...}``) from flat quantities."""
    return {fault.name: LAYOUTS[fault.layout].nested(fault, values) for fault in CATALOGUE}


def flat_from_nested(estimate: dict) -> dict[str, float]:
    """Inverse of :func:`nested` (a report's ``estimate``); KeyError/TypeError when incomplete."""
    out = {}
    for fault in CATALOGUE:
        value = estimate[fault.name]
        for q in fault.quantities:
            out[q.name] = float(value if q.key is None else value[q.key])
    return out


def reference_form(values: dict[str, float]) -> FaultParams:
    """Kernel form for the Reference Model (eccentricity as zeta)."""
    return FaultParams(*(float(values[name]) for name in QUANTITIES))


def values_of(faults: FaultParams) -> dict[str, float]:
    """The quantities of a kernel-form :class:`FaultParams`, keyed as :data:`QUANTITIES`."""
    return dict(zip(QUANTITIES, (float(v) for v in faults)))


def monitor_form(values: dict[str, float], eccentricity_gain: float) -> MonitorFaults:
    """Kernel form for the Monitor Model: Z = ``eccentricity_gain`` zeta (the one conversion)."""
    row = [float(values[name]) for name in QUANTITIES]
    row[ZETA_COLUMN] = eccentricity_gain * row[ZETA_COLUMN]
    return MonitorFaults(*row)


#: Column of zeta (Z in the Monitor's rows) in kernel order.
ZETA_COLUMN = list(QUANTITIES).index("eccentricity_zeta")


def severity(fault: str, values: dict[str, float]) -> float:
    """The scalar a fault's health thresholds apply to (:attr:`Fault.severity` says which).

    The largest deviation from healthy of the fault's magnitudes: ``|k_f - 1|``
    for friction, the play, the worst phase's shorted fraction, zeta.
    """
    return max(abs(values[q.name] - q.healthy) for q in FAULTS[fault].magnitudes)


def incipient_thresholds(health) -> dict[str, float]:
    """Each catalogue fault's incipient severity in a parameter set's ``health:`` section."""
    return {f.name: getattr(health, f.name).incipient for f in CATALOGUE}


def fault_load(values, incipient: dict[str, float]):
    """How much fault a recording carries: the sum over the faults of their severity
    (:func:`severity`) over their incipient threshold ``incipient[fault]`` [-]. 0 on a
    healthy unit, 1 for one fault at its incipient threshold. ``values`` may hold floats or
    equal-length arrays (a campaign's estimates)."""
    total = sum(
        np.max(
            [
                np.abs(np.asarray(values[q.name], dtype=np.float64) - q.healthy)
                for q in fault.magnitudes
            ],
            axis=0,
        )
        / incipient[fault.name]
        for fault in CATALOGUE
    )
    return float(total) if np.ndim(total) == 0 else total


def worst_phase(values: dict[str, float], fault: str) -> str | None:
    """The phase with the per-phase ``fault``'s largest value (a short circuit: its shorted
    fraction), or None if all are zero."""
    fractions = {str(q.key): values[q.name] for q in FAULTS[fault].quantities}
    phase = max(fractions, key=lambda p: fractions[p])
    return phase if fractions[phase] > 0 else None
