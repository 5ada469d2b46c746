"""How sure an identification is: noise floor, identifiability, 90 % intervals, isolation.

Three questions, answered after the optimiser has its estimate:

1. **Does the Monitor explain the recording?** The recording's own noise floor
   is estimated from its high-frequency part (:func:`noise_sigma`, a robust
   second-difference estimate that passes the slow signal and resolves the
   ADC step), and turned into the fitness a perfect model would reach on that
   recording: the 1 ms mean leaves ``sigma^2 / width`` of white noise on every
   filtered sample. ``explained`` is ``fitness <= limit x floor``, the limit
   :data:`MAX_FLOOR_RATIO` (chosen by measurement; see its comment) or, for a unit
   of another form, its calibration's (:func:`floor_ratio_limit`). When it is not,
   every verdict is ``inconclusive``.

2. **What does the recording determine?** The Jacobian of the filtered,
   weighted residual (the vector whose squared norm is the fitness) with
   respect to each estimated quantity, by finite differences of the Monitor at
   the estimate, with unquantised feedback (as in commissioning: the ADC makes
   the residual a staircase in the parameters). Eccentricity is differentiated
   in the plane ``(zeta cos phi, zeta sin phi)``, where it is smooth. The step is
   :data:`STEP_SHARE` of each search span, :data:`FORM_STEP_SHARE` on a Monitor of another
   form, whose residual jumps at that scale.

3. **How far can each estimate be off?** The linearised covariance of a
   weighted least-squares estimate with correlated residuals, the sandwich
   ``A^-1 B A^-1``, ``A = J^T J``, ``B = sum_b s_b^2 L_b J_b^T J_b`` over the
   signal blocks ``b`` (current, position, speed), ``s_b^2`` the block's
   residual variance and ``L_b`` its correlation length in samples
   (:func:`correlation_length`: the effective sample count is ``n / L``). That
   sees the noise but not the Monitor's deterministic mismatch with the motor,
   which dominates on clean recordings (measured on the quick campaign: 32-70 %
   coverage as it is). Each quantity's standard error is widened by its
   :class:`~emaprog.faults.ModelError` law, ``sqrt((factor sigma)^2 + (share d)^2 +
   (load L)^2)`` with ``d`` the estimate's deviation from healthy (the Monitor's signature
   error grows with the fault) and ``L`` the recording's fault load (the other faults'
   signature errors pull this estimate too), one law for a twin experiment
   (:func:`is_twin`: the trace is the Reference Model with this very set) and one for a
   unit's own set, each calibrated on its own calibration campaign to 90 % coverage on
   healthy and on faulty truths and over the range of fault loads
   (``benchmarks/interval_factors.py``). The 90 % interval is
   ``estimate +- 1.645 sigma`` clipped to the quantity's range (zeta's from 0 when the
   estimate is consistent with a healthy rotor: :func:`quantity_interval`); the
   eccentricity phase gets an arc (the whole circle when the phase is not
   determined). A fault whose severity interval holds the healthy value and
   reaches the incipient threshold is not determined by the recording (it cannot
   tell nominal from incipient): ``inconclusive``, and its number is not
   presented as a finding. An interval clear of the healthy value is a finding
   however wide it is.

Short-circuit isolation: the fitness penalty of moving the short onto the next
most likely phase, as a chi-square difference on the effective sample count,
and the two-hypothesis probability ``1 / (1 + exp(-dchi2 / 2))``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..errors import past_limit
from ..faults import (
    CATALOGUE,
    FAULTS,
    MODEL_ERRORS,
    PHASE_FAULTS,
    QUANTITIES,
    ModelError,
    fault_load,
    incipient_thresholds,
    severity,
    worst_phase,
)
from ..models.bldc import Plant
from ..signals import correlation_length, noise_sigma
from .objective import NUISANCE_DEFAULTS, SIGNALS, Objective, fine_plant, low_pass

Z90 = 1.6448536269514722  # two-sided 90 % quantile of the normal distribution
#: 90 % quantile of the length of a 2-D normal vector of zero mean, over its per-axis sigma
#: (Rayleigh: sqrt(-2 ln 0.1)); see :func:`quantity_interval`.
RAYLEIGH90 = 2.1459660262893472
#: [-] fitness over the recording's noise floor above which the Monitor does not explain it.
#: Measured (fitness / floor, min / median / max): quick campaign 1.7 / 2.5 / 5.0, regression
#: 1.5 / 2.1 / 2.7, robustness commissioned 2.0 / 3.5 / 22.3 (the largest under 50-90 N m
#: hinge moments: a high-current recording shows the Monitor's relative mismatch further
#: above its noise); the same spread units on the shipped set 4.8 / 16 / 198, a hinge
#: moment of 60 N m left out of the model 1180, a 2e-5 rad command 69. Above every twin
#: case measured (twins: max 18.8 of the 400 calibration cases, 9.2 of the 200 quick ones)
#: and nearly every commissioned one, below most recordings of a unit the set is not. With
#: the 32 x 20 GA a few commissioned units land above it (robustness 25-31 in 3 of 200,
#: median 3.1; calibration units 28-109 in 4 of 400, median 2.9): `inconclusive`, never an
#: alarm.
MAX_FLOOR_RATIO = 25.0
#: What a recording must hold to support any verdict (:func:`uninformative`): the fitted
#: stretch [s] (the commissioning minimum: a 0.1 s Fig. 10 recording read friction 3.79 for
#: 1.5 and the short circuit 0.205 for 0.12), the motor's peak speed as a share of the speed
#: limit (at rest or under a command too small to pass the friction nothing is excited), and
#: the noise floor's share of the filtered signal's energy (a recording that is mostly noise
#: is "explained" by any fit: at rest the floor is about the whole signal; the shipped noise
#: levels give 1e-5 on the standard test command, 20 x that noise 5e-3).
MIN_FIT_SECONDS = 0.2
MIN_PEAK_SPEED_SHARE = 0.05
MAX_FLOOR_SHARE = 0.05
#: [-] isolation confidence under which a flagged short circuit's phase is not named (the
#: two most likely phases are given instead). On every campaign of this stop each named
#: phase had at least this confidence and none was wrong (quick, robustness, uncommissioned,
#: calibration: 832 named); a 2 kHz recording without a speed channel split 0.064 / 0.060 between A (the wrong phase) and B at 63 %.
MIN_PHASE_CONFIDENCE = 0.9


def named_phase(
    values: dict[str, float],
    fault: str,
    flagged: bool,
    isolation: dict | None,
    basis: str = "unit",
    suspect: bool = False,
) -> str | None:
    """The phase a verdict names for the per-phase ``fault``: the worst one, when the fault
    is flagged and told from the runner-up with at least :data:`MIN_PHASE_CONFIDENCE`; on
    :data:`CLEAR_FINDING_BASES` also only when their 90 % intervals are apart (on the first
    robustness-pwm run with the form's laws, 119 shorts named, one on the wrong phase: a
    short on C of 0.19 read as A 0.121 [0.078, 0.164] beside C 0.079 [0.045, 0.113] at 98 %
    confidence; with the intervals apart, 110 named, none wrong).

    ``suspect``: the fault is ``inconclusive`` at its threshold only (:attr:`Confidence.
    at_threshold`: its interval clear of healthy but not of the incipient threshold): the
    phase is named as the suspect one under the same confidence and, on every basis, with
    its interval apart from the runner-up's. On the form campaigns stored on 2026-12-06 and
    -07 (robustness-pwm three times, calibration-pwm three times) 12 such verdicts had their
    worst phase's interval apart from the runner-up's, all 12 on the truly shorted phase
    (true fractions 0.040-0.064 read 0.051-0.068)."""
    if not (flagged or suspect):
        return None
    if isolation is None:
        return None if suspect else worst_phase(values, fault)
    if isolation["confidence"] < MIN_PHASE_CONFIDENCE:
        return None
    if (suspect or basis in CLEAR_FINDING_BASES) and not isolation["separated"]:
        return None
    return worst_phase(values, fault)


#: Finite-difference step per quantity, as a share of its search span.
STEP_SHARE = 2e-3
#: ... on a Monitor of another form than the hysteresis drive with an ideal chain (a PWM
#: drive's loop, a logger's filters): its residual is a staircase in the parameters, with
#: jumps (an event a Monitor step earlier or later) as large as the slope over a few
#: steps, so a difference over :data:`STEP_SHARE` measures the jumps. Measured on
#: robustness-pwm units at their estimates, the secant over k x 2e-3 of the span for
#: k = 0.5, 1, 2, 5, 10, 20, 50: shorted fractions 3.0, 1.6, 0.80, 0.56, 0.49, 0.43, 0.39,
#: the eccentricity's x 0.12, 0.52, 0.32, 0.31, 0.22, 0.18, 0.16 (under the hysteresis drive
#: within +-25 % at every k). At 2e-3 a healthy rotor's zeta sigma read 0.014-0.019 and a
#: faulty one's 0.003-0.004 on the same recordings, at 5e-2 both 0.006-0.02: the difference
#: was the jumps. A twentieth of the span is the slope over the range the intervals span;
#: with it the form's calibrated model-error factors fell from 2.7-17 to 1.0-9.9.
FORM_STEP_SHARE = 5e-2
#: The nuisances' model-error laws (deviation: from :data:`~.objective.NUISANCE_DEFAULTS`),
#: calibrated like the faults' on the 400 calibration units (``benchmarks/interval_factors.py``:
#: the linearised error alone held the true hinge moment in 21 % of them and the resistance
#: factor in 44 %; the commissioned set's own errors, e.g. in k_e, scale both), used for twin
#: experiments too (which estimate nuisances only when asked).
NUISANCE_ERROR = {q: ModelError(*law) for q, law in MODEL_ERRORS["laws"]["nuisance"].items()}
#: The fault quantities' laws for a unit identified against a set that was not fitted to it
#: (:func:`basis_of` "shipped": the shipped set on a real actuator), calibrated like the
#: others on ``campaigns/calibration-uncommissioned.yaml`` (400 spread units, no
#: commissioning): with the unit laws their intervals held the truth in 26 % (friction) and
#: 56-60 % (short circuit) of those units; checked on robustness-uncommissioned.yaml (50):
#: friction 88 %, backlash 94 %, short circuit 92-96 %, zeta 94 %, phase 91 %. Wide: a unit
#: whose set is not its own reads its inertia and friction mismatch as faults.
SHIPPED_ERROR: dict[str, ModelError] = {
    q: ModelError(*law) for q, law in MODEL_ERRORS["laws"]["shipped"].items()
}


#: The bases of a commissioned unit of another form than the hysteresis one: "form", its
#: Monitor commutating on its own motor angle, and "form_angle", on the recording's
#: (docs/reference.md, The models): two Monitors, two error laws, each calibrated on
#: ``campaigns/calibration-pwm.yaml`` identified so.
FORM_BASES = ("form", "form_angle")
#: Every quantity's and nuisance's law on each of :data:`FORM_BASES` (docs/reference.md,
#: Confidence).
FORM_ERRORS: dict[str, dict[str, ModelError]] = {
    basis: {q: ModelError(*law) for q, law in MODEL_ERRORS["laws"][basis].items()}
    for basis in FORM_BASES
}


class NoiseFloor(NamedTuple):
    sigma: dict[str, float]  # per signal, raw samples [its unit]
    fitness: float  # the fitness a model with no error would reach on this recording [-]
    ratio: float  # the identification's fitness over it [-]
    explained: bool
    limit: float = MAX_FLOOR_RATIO  # the ratio up to which the Monitor explains it [-]


class Confidence(NamedTuple):
    floor: NoiseFloor
    interval: dict[str, tuple[float, float]]  # per estimated quantity [low, high]
    standard_error: dict[str, float]  # per estimated quantity (eccentricity: zeta, phase)
    inconclusive: dict[str, str]  # fault -> why (only the inconclusive ones)
    isolation: dict[str, dict | None]  # per-phase fault -> its named phase's confidence
    method: str
    twin: bool  # the twin experiment's model-error laws were used (:func:`is_twin`)
    linear_error: dict[str, float]  # the linearised standard errors, before the laws
    fault_load: float  # the estimate's :func:`~emaprog.faults.fault_load` [-]
    basis: str = "unit"  # which model-error laws were used (:data:`BASES`)
    echo: dict | None = None  # off the calibration: {"reasons", "errors"} (:mod:`.echo`)
    #: the faults ``inconclusive`` only because their interval does not clear the incipient
    #: threshold while it clears healthy (the fit explained, the recording informative)
    at_threshold: tuple[str, ...] = ()
    #: the basis whose explained limit the fit passed, when :data:`WIDER_BASIS` gave ``basis``
    #: (None: ``basis`` is the recording's own, :func:`basis_of`); campaigns calibrate by it
    past_limit_of: str | None = None


def noise_floor(
    objective: Objective, trace, fitness: float, limit: float = MAX_FLOOR_RATIO
) -> NoiseFloor:
    """The recording's noise floor in fitness units, and how far the fit is above it (at
    most ``limit`` times: explained)."""
    sensors = objective.params.plant.sensors
    lsb = {
        "current": sensors.current_lsb,
        "position": sensors.position_lsb,
        "speed": sensors.speed_lsb,
    }
    target = objective.target
    total = float(target.sample_weight.sum())
    sigma, floor = {}, 0.0
    for s, name in enumerate(SIGNALS):
        sigma[name] = noise_sigma(trace[name], lsb[name])
        if target.weights[s] == 0.0:
            continue
        # the fitness's own denominator: the signal's norm about its centre (the target's)
        norm = float(target.norms[s])
        floor += target.weights[s] * total * sigma[name] ** 2 / objective.measured_width / norm
    floor = max(floor, 1e-30)
    ratio = fitness / floor
    return NoiseFloor(sigma, floor, ratio, bool(ratio <= limit), limit)


def uninformative(objective: Objective, trace, floor: NoiseFloor) -> str | None:
    """Why the recording cannot support a verdict (None: it can); see :data:`MIN_FIT_SECONDS`."""
    weight = objective.target.sample_weight
    fitted = float(weight.sum()) / trace.sample_rate
    if fitted < MIN_FIT_SECONDS:
        return (
            f"the recording is too short to judge: {fitted:.3g} s fitted (after the "
            f"start-up window), at least {MIN_FIT_SECONDS:g} s of the standard test command "
            "are needed"
        )
    limit = objective.params.spec.controller.speed_limit
    speed = np.abs(low_pass(trace["speed"], objective.measured_width))
    peak = float(np.max(speed[weight > 0])) if np.any(weight > 0) else 0.0
    if peak < MIN_PEAK_SPEED_SHARE * limit:
        return (
            f"the recording does not excite the actuator: peak motor speed {peak:.3g} rad/s, "
            f"below {MIN_PEAK_SPEED_SHARE:.0%} of the {limit:g} rad/s limit (at rest, or a "
            "command too small to pass the friction); record the standard test command"
        )
    if floor.fitness > MAX_FLOOR_SHARE:
        return (
            f"the recording is mostly noise: its noise floor is {floor.fitness:.2g} of the "
            f"filtered signal's energy (at most {MAX_FLOOR_SHARE:g}), so no fit can be told "
            "from another"
        )
    return None


def information_inverse(information: np.ndarray) -> np.ndarray:
    """``(J^T J)^-1``, with infinite variance along directions the data do not constrain at
    all (a parameter that changes nothing, e.g. static friction when the motor never sticks)."""
    eigenvalues, vectors = np.linalg.eigh(information)
    floor = 1e-12 * max(float(eigenvalues.max()), 1e-300)
    cov = (vectors / np.maximum(eigenvalues, floor)) @ vectors.T
    blind = vectors[:, eigenvalues <= floor]
    if blind.size:
        touched = np.any(np.abs(blind) > 1e-3, axis=1)
        cov[touched, touched] = np.inf  # their variances (the diagonal)
    return cov


# ------------------------------------------------------------------ coordinates
class _Coordinate(NamedTuple):
    name: str  # a quantity, a nuisance, or "eccentricity_x" / "eccentricity_y"
    lower: float
    upper: float
    step: float


class _Plane(NamedTuple):
    """The polar fault's magnitude and angle, and its Cartesian coordinates' names."""

    fault: str
    magnitude: str
    angle: str
    x: str
    y: str


def _planes(catalogue=CATALOGUE) -> tuple[_Plane, ...]:
    """Every polar fault's plane, in catalogue order."""
    planes = []
    for fault in catalogue:
        if fault.layout == "polar":
            m, a = (q.name for q in fault.quantities)
            planes.append(_Plane(fault.name, m, a, f"{fault.name}_x", f"{fault.name}_y"))
    return tuple(planes)


PLANES = _planes()
POLAR_MAGNITUDES = frozenset(p.magnitude for p in PLANES)
#: Each polar fault's Cartesian coordinates (not quantities of their own).
PLANE_COORDINATES = frozenset(n for p in PLANES for n in (p.x, p.y))


def _coordinates(
    objective: Objective, values: dict[str, float], planes: tuple[_Plane, ...] = PLANES
) -> tuple[list[_Coordinate], dict]:
    """The smooth coordinates of the estimate: genes, each polar fault in its plane, each with
    its finite-difference step (:data:`STEP_SHARE`, :data:`FORM_STEP_SHARE`)."""
    share = STEP_SHARE if objective.params.hysteresis_form else FORM_STEP_SHARE
    coords, point = [], {}
    angles = {p.angle for p in planes}
    by_magnitude = {p.magnitude: p for p in planes}
    for gene in objective.genes:
        step = share * (gene.upper - gene.lower)
        if gene.quantity in angles:
            continue
        plane = by_magnitude.get(gene.quantity)
        if plane is not None:
            r, angle = values[plane.magnitude], values[plane.angle]
            for name, v in ((plane.x, r * math.cos(angle)), (plane.y, r * math.sin(angle))):
                coords.append(_Coordinate(name, -gene.upper, gene.upper, step))
                point[name] = v
            continue
        coords.append(_Coordinate(gene.quantity, gene.lower, gene.upper, step))
        point[gene.quantity] = values[gene.quantity]
    return coords, point


#: The bases of the model-error laws: a twin experiment (the trace is emaprog's Reference
#: Model with this very set), a unit identified against its own commissioned set, a unit
#: identified against a set that was not fitted to it (the shipped set on a real actuator),
#: and a commissioned unit of another form than the hysteresis drive with an ideal sensor
#: chain (:attr:`~emaprog.config.parameters.Parameters.hysteresis_form`; calibrated on PWM
#: units logged through a real chain under an aerodynamic spring), without and with a
#: recorded motor angle (:data:`FORM_BASES`).
BASES = ("twin", "unit", "shipped", *FORM_BASES)


def basis_of(
    twin: bool, commissioned: bool, hysteresis_form: bool = True, motor_angle: bool = False
) -> str:
    """Which laws apply (:data:`BASES`); ``motor_angle``: the Monitor commutated on the
    recording's."""
    if twin:
        return "twin"
    if not commissioned:
        return "shipped"
    if hysteresis_form:
        return "unit"
    return "form_angle" if motor_angle else "form"


def quantity_error(name: str, basis: str | bool = "unit") -> ModelError:
    """The model-error law of a fault quantity on a :data:`BASES` basis (``True``/``False``:
    twin/unit): :attr:`~emaprog.faults.Fault.model_error` for a unit's own set,
    :attr:`~emaprog.faults.Fault.twin_error` in a twin experiment, :data:`SHIPPED_ERROR`
    for a set not fitted to the unit; a nuisance's :data:`NUISANCE_ERROR` on every basis."""
    basis = {True: "twin", False: "unit"}.get(basis, basis) if isinstance(basis, bool) else basis
    if basis == "shipped" and name in SHIPPED_ERROR:
        return SHIPPED_ERROR[name]
    if basis in FORM_ERRORS:
        return FORM_ERRORS[basis][name]
    for fault in CATALOGUE:
        laws = fault.twin_error if basis == "twin" else fault.model_error
        for q, law in zip(fault.quantities, laws):
            if q.name == name:
                return law
    return NUISANCE_ERROR[name]


#: Per basis, the fit-to-floor ratio under which its model-error laws were calibrated: the
#: 95th percentile over its calibration campaign (``benchmarks/interval_factors.py``). A
#: recording the Monitor explains worse than that (another command, another form of unit)
#: carries more model mismatch than the laws saw: its standard errors are widened by
#: ``sqrt(ratio / MISMATCH_RATIO)`` (:func:`mismatch_widening`). Measured on twins driven by a
#: 0.05 rad step (campaigns/off-calibration/step.yaml, fit ratio median 31): the friction
#: interval held its truth in 67 % of the conclusive cases before.
MISMATCH_RATIO: dict[str, float] = dict(MODEL_ERRORS["mismatch_ratio"])


#: The bases on which a fault is flagged only when its whole 90 % severity interval is at
#: or above the incipient threshold (elsewhere the estimate decides once the interval is
#: clear of healthy). On the form basis the errors are of the thresholds' size: on 133 of
#: campaigns/robustness-pwm.yaml's units, with the estimate deciding, 8 of 33 healthy units
#: were flagged (intervals at 90 % coverage miss healthy about one time in twenty per
#: fault, and four faults are judged); with the whole interval, none, detection 68-88 %
#: (docs/reference.md, Confidence).
CLEAR_FINDING_BASES = frozenset(FORM_BASES)


#: The bases whose explained limit is measured on their calibration units, not
#: :data:`MAX_FLOOR_RATIO`: the form's (the PWM form's Monitor explains a unit's recording
#: less closely than the hysteresis one, and its laws are calibrated on such fits).
EXPLAINED_LIMIT_BASES = frozenset(FORM_BASES)
#: Per basis of :data:`EXPLAINED_LIMIT_BASES`, the fit-to-floor ratio up to which the Monitor
#: explains a recording: the worst fit among its calibration units, rounded up
#: (``benchmarks/interval_factors.py``). Every one of them was identified, and its
#: interval counted, when the laws were calibrated; a fit above their 95th percentile
#: (:data:`MISMATCH_RATIO`) widens the intervals, one above the worst is not explained.
#: A limit at the 95th percentile itself would make one unit in twenty of the calibrated
#: form `inconclusive` by construction.
EXPLAINED_LIMIT: dict[str, float] = dict(MODEL_ERRORS["explained_limit"])


#: Per basis, the basis whose laws apply to a recording it does not explain (a fit past its
#: :data:`EXPLAINED_LIMIT`). The recorded motor angle only takes the commutation's error out
#: of the Monitor (docs/explanation/validation-and-speed.md): a unit whose recording it still
#: explains worse than the worst of the PWM form's calibration units carries model error
#: of another kind (its friction law, cogging, its back-EMF's shape), which the own-angle
#: laws, calibrated on fits up to their own, wider limit, cover more widely; past that
#: limit too the verdict is ``inconclusive``.
WIDER_BASIS: dict[str, str] = {"form_angle": "form"}


def floor_ratio_limit(basis: str) -> float:
    """The fit-to-floor ratio up to which the Monitor explains a recording on ``basis``:
    :data:`MAX_FLOOR_RATIO`, or on :data:`EXPLAINED_LIMIT_BASES` the worst fit its laws
    were calibrated on (:data:`EXPLAINED_LIMIT`; docs/reference.md, Confidence)."""
    return EXPLAINED_LIMIT[basis] if basis in EXPLAINED_LIMIT_BASES else MAX_FLOOR_RATIO


def judging_basis(objective: Objective, trace, fitness: float, basis: str) -> str:
    """The basis whose laws judge a recording of ``basis`` (:func:`basis_of`): ``basis``, or
    its :data:`WIDER_BASIS` when the fit lies past ``basis``' explained limit."""
    wider = WIDER_BASIS.get(basis)
    if wider is None or noise_floor(objective, trace, fitness, floor_ratio_limit(basis)).explained:
        return basis
    return wider


def mismatch_widening(ratio: float, basis: str) -> float:
    """How much wider than its laws say a recording's standard errors are [-] (>= 1)."""
    return max(1.0, math.sqrt(ratio / MISMATCH_RATIO[basis])) if math.isfinite(ratio) else 1.0


def widened(law: ModelError, sigma: float, deviation: float, load: float = 0.0) -> float:
    """The standard error of :class:`~emaprog.faults.ModelError` ``law`` for a linearised
    ``sigma``, an estimate ``deviation`` from healthy and the recording's fault ``load``
    (:func:`~emaprog.faults.fault_load`)."""
    return math.hypot(law.factor * sigma, law.share * deviation, law.load * load)


def is_twin(trace, params) -> bool:
    """Whether ``trace`` is emaprog's Reference Model run with exactly the physical values of
    ``params`` (a twin experiment: the trace's provenance says so). A rig recording, or a
    trace of another unit, never is."""
    meta = getattr(trace, "metadata", None) or {}
    recorded = meta.get("parameters") or {}
    values = params.values()
    return meta.get("model") == "reference" and all(
        recorded.get(section) == values[section]
        for section in ("electrical", "mechanical", "controller", "sensors")
    )


def _values(
    base: dict[str, float], point: dict[str, float], planes: tuple[_Plane, ...] = PLANES
) -> dict[str, float]:
    """Fault values of a point in the coordinates (each plane back to magnitude and angle)."""
    coordinates = {n for p in planes for n in (p.x, p.y)}
    out = {**base, **{k: v for k, v in point.items() if k not in coordinates}}
    for plane in planes:
        if plane.x in point:
            x, y = point[plane.x], point[plane.y]
            out[plane.magnitude] = math.hypot(x, y)
            out[plane.angle] = math.atan2(y, x) % (2.0 * math.pi)
    return out


def residual_vector(
    objective: Objective, values: dict[str, float], plant: Plant | None = None
) -> tuple[np.ndarray, list[int]]:
    """The weighted, filtered residual whose squared norm is the fitness, and its blocks
    (one per signal the fitness uses)."""
    residual = objective.residuals(objective.genes_for(values)[None], plant)[0]
    signals = int(np.count_nonzero(objective.target.weights))
    return residual, [residual.size // signals] * signals


def jacobian(
    objective: Objective, values: dict[str, float]
) -> tuple[list[_Coordinate], np.ndarray]:
    """d residual / d coordinate at ``values`` (central differences, one-sided at a bound),
    every perturbed Monitor in one batch, with unquantised feedback."""
    coords, point = _coordinates(objective, values)
    rows, spans = [], []
    for c in coords:
        up = min(point[c.name] + c.step, c.upper)
        down = max(point[c.name] - c.step, c.lower)
        if up - down <= 0.0:
            up, down = point[c.name] + c.step, point[c.name]
        rows += [objective.genes_for(_values(values, {**point, c.name: x})) for x in (up, down)]
        spans.append(up - down)
    if not rows:
        return coords, np.zeros((0, 0))
    moved = objective.residuals(np.array(rows), fine_plant(objective.params.plant))
    return coords, ((moved[0::2] - moved[1::2]) / np.array(spans)[:, None]).T


def covariance(jac: np.ndarray, residual: np.ndarray, blocks: list[int]) -> np.ndarray:
    """Sandwich covariance of the weighted least-squares estimate (module docstring).

    Worked out on the Jacobian's columns scaled to unit norm, then scaled back: whether a
    direction is constrained at all must not depend on the units of its coordinate (an
    aerodynamic spring in N m/rad beside a shorted fraction read as blind in raw units)."""
    scale = np.sqrt(np.sum(jac * jac, axis=0))
    scale = np.where(scale > 0.0, scale, 1.0)
    jac = jac / scale
    a_inv = information_inverse(jac.T @ jac)
    middle = np.zeros((jac.shape[1], jac.shape[1]))
    edges = np.cumsum([0, *blocks])
    dof_share = max(1.0 - jac.shape[1] / max(residual.size, 1), 0.5)
    for lo, hi in zip(edges[:-1], edges[1:]):
        r, j = residual[lo:hi], jac[lo:hi]
        s2 = float(r @ r) / (r.size * dof_share)
        middle += s2 * correlation_length(r, [r.size]) * (j.T @ j)
    finite = np.isfinite(np.diag(a_inv))
    cov = np.full_like(a_inv, np.inf)
    sub = np.ix_(finite, finite)
    cov[sub] = a_inv[sub] @ middle[sub] @ a_inv[sub]
    return cov / np.outer(scale, scale)


def quantity_interval(name: str, value, se):
    """The 90 % interval of a fault quantity from its estimate and standard error (floats
    or arrays): ``value +- 1.645 se`` clipped to the quantity's range. A polar magnitude
    (zeta) is the length of a 2-D estimate, which is never negative: on a healthy rotor it
    is Rayleigh-distributed and exceeds ``1.645 se`` in 26 % of cases, its 90 % quantile is
    :data:`RAYLEIGH90` ``se``. An estimate within that of zero is therefore consistent with
    zero, and its interval starts at 0."""
    q = QUANTITIES[name]
    low = value - Z90 * se
    if name in POLAR_MAGNITUDES:
        low = np.where(value <= RAYLEIGH90 * se, q.lower, low)
    low, high = np.maximum(low, q.lower), np.minimum(value + Z90 * se, q.upper)
    return (float(low), float(high)) if np.ndim(low) == 0 else (low, high)


def assess(
    objective: Objective,
    trace,
    values: dict[str, float],
    fitness: float,
    estimated: list[str],
    health_limits,
    twin: bool = False,
    basis: str | None = None,
    echo: dict | None = None,
) -> Confidence:
    """Noise floor, intervals, identifiability and isolation of one identification;
    ``basis`` (:data:`BASES`) which model-error laws apply (default: twin or unit);
    ``echo`` (:mod:`.echo`, ``{"reasons", "errors"}``) the echo twin's error per quantity:
    taken into each standard error in quadrature, and the interval also spans the one about
    the estimate less that error (the bootstrap's bias correction; an arc widens by it)."""
    basis = basis or ("twin" if twin else "unit")
    floor = noise_floor(objective, trace, fitness, floor_ratio_limit(basis))
    residual, blocks = residual_vector(objective, values)
    coords, jac = jacobian(objective, values)
    cov = covariance(jac, residual, blocks)
    linear = {
        c.name: math.sqrt(cov[k, k]) if np.isfinite(cov[k, k]) else math.inf
        for k, c in enumerate(coords)
    }
    linear.update(_polar_errors(coords, cov, values))
    interval, standard_error = {}, {}
    load = fault_load(values, incipient_thresholds(health_limits))
    widening = mismatch_widening(floor.ratio, basis)
    # the echo's error less what its own noise explains: sign(e) sqrt(e^2 - sigma^2), with
    # sigma the linearised (noise) standard error; on twins with five times the noise the
    # raw error widened PSC B's intervals to 99 % coverage, this to 97 %
    signed = {
        k: math.copysign(math.sqrt(max(e * e - linear.get(k, 0.0) ** 2, 0.0)), e)
        if math.isfinite(linear.get(k, 0.0))
        else 0.0
        for k, e in (echo or {}).get("errors", {}).items()
    }
    echoed = {k: abs(v) for k, v in signed.items()}
    for name, s in linear.items():
        if name in PLANE_COORDINATES:
            continue
        q = QUANTITIES.get(name)
        if q is None:  # a nuisance: never a verdict, an interval all the same
            deviation = abs(values[name] - NUISANCE_DEFAULTS[name])
            se = standard_error[name] = math.hypot(
                widening * widened(quantity_error(name, basis), s, deviation, load),
                echoed.get(name, 0.0),
            )
            shift = signed.get(name, 0.0)
            interval[name] = (
                min(values[name], values[name] - shift) - Z90 * se,
                max(values[name], values[name] - shift) + Z90 * se,
            )
            continue
        deviation = 0.0 if q.circular else abs(values[name] - q.healthy)
        standard_error[name] = math.hypot(
            widening * widened(quantity_error(name, basis), s, deviation, load),
            echoed.get(name, 0.0),
        )
        if q.circular:
            arc = Z90 * standard_error[name] + echoed.get(name, 0.0)
            interval[name] = (
                (0.0, 2.0 * math.pi) if arc >= math.pi else (values[name] - arc, values[name] + arc)
            )
        else:
            interval[name] = quantity_interval(name, values[name], standard_error[name])
            if name in signed:  # and about the echo's bias-corrected estimate
                other = quantity_interval(name, values[name] - signed[name], standard_error[name])
                interval[name] = (
                    min(interval[name][0], other[0]),
                    max(interval[name][1], other[1]),
                )
    linear = {name: s for name, s in linear.items() if name not in PLANE_COORDINATES}
    inconclusive = {}
    at_threshold: list[str] = []
    why_not = uninformative(objective, trace, floor)
    for fault in estimated:
        if why_not is not None:
            inconclusive[fault] = why_not
            continue
        if not floor.explained:
            inconclusive[fault] = (
                f"the Monitor does not explain the recording: fitness "
                f"{fitness:.3g} is {past_limit(floor.ratio, floor.limit, '.0f')} x the recording's noise "
                f"floor {floor.fitness:.3g} (at most {floor.limit:g} x)"
            )
            continue
        why = interval_verdict(
            fault, values, interval, getattr(health_limits, fault).incipient, basis
        )
        if why is not None:
            inconclusive[fault] = why
            low, high = severity_interval(fault, interval)
            if low > 0.0 and math.isfinite(high):
                at_threshold.append(fault)
    phased = [fault for fault in PHASE_FAULTS if fault in estimated]
    length = correlation_length(residual, blocks) if phased else 0.0
    isolation = {
        fault: _isolation(objective, fault, values, fitness, residual.size, length, interval)
        for fault in phased
    }
    described = {
        "twin": "twin experiment (the trace is the Reference Model with this very set)",
        "unit": "a unit's own parameter set",
        "shipped": "a parameter set not fitted to this unit",
        "form": "a unit's own parameter set, of a form other than the hysteresis drive with "
        "an ideal sensor chain",
        "form_angle": "a unit's own parameter set, of a form other than the hysteresis drive "
        "with an ideal sensor chain, the Monitor commutating on the recorded motor angle",
    }[basis]
    method = (
        "linearised (sandwich) covariance of the weighted least-squares fit at the "
        "estimate, correlated residuals counted by their correlation length, widened by "
        f"each quantity's model-error law for {described}, sqrt((factor sigma)^2 + (share "
        "deviation from healthy)^2 + (load fault_load)^2) (factor/share/load: "
        + ", ".join(
            "{} {:g}/{:g}/{:g}".format(name, *quantity_error(name, basis))
            for name in [*QUANTITIES, *(n for n in NUISANCE_DEFAULTS if n in standard_error)]
        )
        + f"; fault load {load:.3g}; calibrated on separate calibration campaigns to "
        f"90 % coverage; x{widening:.3g} for a fit {floor.ratio:.3g} x its noise floor, "
        f"over the {MISMATCH_RATIO[basis]:g} x the laws were calibrated under)"
    )
    if echo:
        method += (
            "; off the calibration (" + "; ".join(echo["reasons"]) + "): each standard "
            "error takes the echo twin's error in quadrature and the interval spans the one "
            "about the estimate less that error (docs/reference.md, Confidence)"
        )
    return Confidence(
        floor,
        interval,
        standard_error,
        inconclusive,
        isolation,
        method,
        twin,
        linear,
        load,
        basis,
        echo,
        tuple(at_threshold),
    )


def interval_verdict(
    fault: str,
    values: dict[str, float],
    interval: dict[str, tuple[float, float]],
    threshold: float,
    basis: str,
) -> str | None:
    """Why the 90 % intervals cannot support a verdict on ``fault`` at its incipient
    ``threshold`` (None: they can, and the estimate decides): the severity interval holds
    healthy and reaches the threshold, or, on :data:`CLEAR_FINDING_BASES`, the estimate
    reaches the threshold and the interval does not clear it."""
    low, high = severity_interval(fault, interval)
    if not math.isfinite(high) or (low <= 0.0 and high >= threshold):
        return (
            f"the recording cannot tell nominal from incipient: the 90 % "
            f"interval of its severity, [{low:.3g}, {high:.3g}], holds the "
            f"healthy value and reaches the incipient threshold "
            f"{threshold:g}"
        )
    if basis in CLEAR_FINDING_BASES and severity(fault, values) >= threshold > low:
        return (
            f"the estimate reaches the incipient threshold {threshold:g} but the 90 % "
            f"interval of its severity, [{low:.3g}, {high:.3g}], does not clear it (a "
            "unit of another form: a finding needs the whole interval at or above it)"
        )
    return None


def _polar_errors(
    coords: list[_Coordinate],
    cov: np.ndarray,
    values: dict[str, float],
    planes: tuple[_Plane, ...] = PLANES,
) -> dict[str, float]:
    """Each estimated polar fault's linearised errors from its plane's covariance block: the
    magnitude's along the estimate, the angle's across it over the magnitude."""
    out = {}
    for plane in planes:
        k = [i for i, c in enumerate(coords) if c.name in (plane.x, plane.y)]
        if not k:
            continue
        block = cov[np.ix_(k, k)]
        zeta, phase = values[plane.magnitude], values[plane.angle]
        radial = np.array([math.cos(phase), math.sin(phase)])
        tangent = np.array([-math.sin(phase), math.cos(phase)])
        finite = bool(np.all(np.isfinite(block)))
        out[plane.magnitude] = (
            math.sqrt(max(float(radial @ block @ radial), 0.0)) if finite else math.inf
        )
        across = math.sqrt(max(float(tangent @ block @ tangent), 0.0)) if finite else math.inf
        out[plane.angle] = across / zeta if zeta > 0 else math.inf
    return out


def _isolation(
    objective: Objective,
    fault: str,
    values: dict[str, float],
    fitness: float,
    samples: int,
    length: float,
    interval: dict[str, tuple[float, float]],
) -> dict | None:
    """Confidence in the per-phase ``fault``'s named phase against the runner-up (module
    docstring), and whether their 90 % intervals are apart (``separated``)."""
    named = worst_phase(values, fault)
    if named is None:
        return None
    phases = {q.key: q.name for q in FAULTS[fault].quantities}
    others = sorted((p for p in phases if p != named), key=lambda p: -values[phases[p]])
    runner = others[0]
    moved = {**values, phases[named]: values[phases[runner]], phases[runner]: values[phases[named]]}
    alternative = float(objective(objective.genes_for(moved)[None])[0])
    effective = max(samples / max(length, 1.0), 1.0)
    delta = max(alternative - fitness, 0.0) / max(fitness, 1e-300) * effective
    confidence = 1.0 / (1.0 + math.exp(-min(delta, 1400.0) / 2.0))
    separated = bool(interval[phases[named]][0] > interval[phases[runner]][1])
    return {
        "phase": named,
        "runner_up": runner,
        "delta_chi2": delta,
        "confidence": confidence,
        "separated": separated,
    }


def confidence_record(confidence: Confidence) -> dict:
    """The report's ``confidence`` key (JSON types; an unbounded error is null)."""

    def finite(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None

    floor = confidence.floor
    return {
        "method": confidence.method,
        "model_error_basis": confidence.basis,
        "fault_load": confidence.fault_load,
        "noise_floor": {
            "sigma": floor.sigma,
            "fitness": floor.fitness,
            "ratio": floor.ratio,
            "explained": floor.explained,
            "rule": f"explained when fitness <= {floor.limit:g} x the floor"
            + (
                f" (past {floor_ratio_limit(confidence.past_limit_of):g} x, the limit of the "
                f"{confidence.past_limit_of} laws, the {confidence.basis} laws judge)"
                if confidence.past_limit_of
                else ""
            ),
        },
        "standard_error": {q: finite(v) for q, v in confidence.standard_error.items()},
        "inconclusive": confidence.inconclusive,
        "isolation": confidence.isolation,
        "echo": (
            {
                "reasons": confidence.echo["reasons"],
                "errors": {q: float(v) for q, v in confidence.echo["errors"].items()},
            }
            if confidence.echo
            else None
        ),
    }


def severity_interval(fault: str, interval: dict[str, tuple[float, float]]) -> tuple[float, float]:
    """Range of the fault's severity (:func:`~emaprog.faults.severity`) over its magnitudes'
    intervals: 0 at the low end when an interval holds the healthy value."""
    lows, highs = [], []
    for q in FAULTS[fault].magnitudes:
        low, high = interval[q.name]
        lo_s = 0.0 if low <= q.healthy <= high else min(abs(low - q.healthy), abs(high - q.healthy))
        lows.append(lo_s)
        highs.append(max(abs(low - q.healthy), abs(high - q.healthy)))
    return max(lows), max(highs)
