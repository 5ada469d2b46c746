"""Commissioning: fit a unit's own parameter set to recordings of it while healthy.

A real actuator is not the shipped parameter set: inertias, viscous and dry
friction, winding resistance, back-EMF constant, inductance and stiffness vary
from unit to unit, and every recording has its own constant hinge moment. The
Monitor Model (healthy) is fitted to one or more recordings of the unit by
bounded nonlinear least squares (:func:`scipy.optimize.least_squares`, trust
region reflective) on the 1 ms-averaged current, position and speed, each over
its own RMS, at the recorded instants.

Unknowns: the natural logarithm of each parameter's factor on the base value
(the static friction as dynamic friction times a ratio >= 1, so the Borello
model stays valid), and per recording a constant hinge moment [N m] and, when asked
(``spring``), an aerodynamic spring [N m/rad of surface deflection]: operating
conditions, reported, never stored as parameters.

Standard errors come from the Jacobian at the solution,
``cov = s^2 (J^T J)^-1 x width`` with ``s^2`` the residual variance and the
factor ``width`` (samples per 1 ms) for the correlation the moving average puts
between neighbouring residuals. A parameter whose standard error exceeds
:data:`MAX_LOG_ERROR` is not determined by the recordings: it is held at the base
value and the fit is repeated without it (most uncertain first). The weakest
direction of ``J^T J`` among the fitted parameters is reported when it is poorly
constrained: e.g. the torque constant scales with the inertias, viscous,
friction and hinge moment and leaves position, speed and current unchanged
except through the back-EMF.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

import numpy as np
from scipy.optimize import least_squares

from ..config.parameters import COMMISSIONED, Parameters
from ..errors import InputError, past_limit
from ..faults import healthy_values, monitor_form
from ..identification.confidence import correlation_length, information_inverse
from ..identification.objective import (
    STARTUP_SECONDS,
    filter_lag,
    filter_width,
    fine_plant,
    low_pass,
)
from ..io.recordings import derived_speed, speed_source_of
from ..io.storage import Trace
from ..models import monitor
from ..models.bldc import MonitorOutputs, Plant
from ..models.common import Inputs, Instants, inputs_from_trace, recorded_instants
from ..models.family import family_of
from ..numerics import DEFAULT, serial_blas


class Unknown(NamedTuple):
    """A unit parameter commissioning may fit: bounds of its factor on the base value."""

    name: str
    section: str  # "electrical" | "mechanical"
    lower: float  # [-] factor on the base value
    upper: float


#: The unit-to-unit parameters, with plausible bounds (factor on the base value): wider
#: than build tolerances (docs/reference.md, Campaign YAML) so that a bound is never what stops the fit.
UNKNOWNS = (
    Unknown("motor_inertia", "mechanical", 0.6, 1.6),
    Unknown("surface_inertia", "mechanical", 0.6, 1.6),
    Unknown("motor_viscous", "mechanical", 0.2, 5.0),
    Unknown("dynamic_friction", "mechanical", 0.4, 2.5),
    Unknown("static_friction", "mechanical", 0.4, 2.5),  # fitted as dynamic x ratio (>= 1)
    Unknown("phase_resistance", "electrical", 0.6, 1.6),
    Unknown("back_emf_constant", "electrical", 0.85, 1.15),
    Unknown("phase_inductance", "electrical", 0.6, 1.6),
    Unknown("transmission_stiffness", "mechanical", 0.4, 2.0),
)
assert tuple(u.name for u in UNKNOWNS) == COMMISSIONED  # the parameter set's tolerance keys

#: [-] standard error of a log factor above which a parameter counts as not determined
#: (5 %: half the smallest build tolerance (docs/reference.md, Campaign YAML) that matters, the inertias' 10 %).
MAX_LOG_ERROR = 0.05
#: Finite-difference step of the Jacobian (in log factor, and hinge moment / HINGE_SCALE).
DIFF_STEP = 1e-4
#: [-] residual scale of the robust first pass (soft L1).
ROBUST_SCALE = 0.03
#: Monitor steps per controller period in the fit under the hysteresis drive
#: (identification's: 4; see _Problem and :func:`fit_substeps`).
FIT_SUBSTEPS = 16


def fit_substeps(params: Parameters) -> int:
    """The Monitor step of the fit: :data:`FIT_SUBSTEPS` under the hysteresis drive, whose
    Monitor barely depends on its step; under a PWM drive identification's own, because
    there the Monitor does depend on it, and a unit fitted on one step's Monitor was then
    identified on another's (measured: docs/reference.md, Commissioning)."""
    if params.spec.drive.regulator == "pwm":
        return DEFAULT.monitor_substeps
    return FIT_SUBSTEPS


HINGE_SCALE = 100.0  # [N m] hinge moments are fitted in this unit (conditioning)
HINGE_BOUND = 3000.0  # [N m]
SPRING_SCALE = 1000.0  # [N m/rad] aerodynamic springs are fitted in this unit
SPRING_BOUNDS = (-1.0e4, 1.0e5)  # [N m/rad] the nuisance's limits (faults.NUISANCES)
MIN_DURATION = 0.2  # [s] shorter recordings do not excite the slow mechanical terms
MIN_SPEED_SHARE = 0.05  # [-] of the speed limit: below it the motor barely moves
#: [-] current residual RMS over the current RMS above which the Monitor does not
#: explain the recording (noise-free twins: 0.4 %; noisy Reference traces 1-2 %)
MAX_CURRENT_RESIDUAL = 0.10


#: Model-error floors of commissioning's standard errors (relative, and the hinge moment's in
#: N m): the reported standard error is ``sqrt(linearised^2 + floor^2)``. The linearised error
#: sees the recordings' noise, not the Monitor's deterministic mismatch with the unit, which
#: dominates (e.g. surface inertia +5 % at a linearised 1.5 %). Calibrated on the 400
#: calibration units (``benchmarks/commission_errors.py``) to hold the truth within
#: 1.645 standard errors in 90 % of the units where the parameter is fitted; docs/reference.md
#: (Commissioning) gives the coverage before and after, and on the robustness campaign. The
#: static friction is held in nearly every unit; it takes the dynamic friction's floor.
MODEL_ERROR_FLOOR = {
    "motor_inertia": 0.040,
    "surface_inertia": 0.0462,
    "motor_viscous": 0.108,
    "dynamic_friction": 0.0238,
    "static_friction": 0.0238,
    "phase_resistance": 0.0516,
    "back_emf_constant": 0.0309,
    "phase_inductance": 0.010,
    "transmission_stiffness": 0.0447,
    "hinge_moment": 1.81,
}


def reported_error(name: str, value: float, linearised: float) -> float:
    """The standard error reported for a fitted parameter [its unit] (or the hinge moment
    [N m], ``value`` ignored): the linearised one widened by :data:`MODEL_ERROR_FLOOR`."""
    floor = MODEL_ERROR_FLOOR.get(name, 0.0)
    if name == "hinge_moment":
        return math.hypot(linearised, floor)
    return abs(value) * math.hypot(linearised / abs(value), floor)


class Recording(NamedTuple):
    """One healthy recording prepared for the fit."""

    source: str
    trace: Trace
    inputs: Inputs
    instants: Instants
    measured: tuple[np.ndarray, np.ndarray, np.ndarray]  # 1 ms means: current, position, speed
    scales: np.ndarray  # (3,) RMS of each measured signal over the fitted samples
    mask: np.ndarray  # (n_rec,) bool: samples in the fit (after the start-up window)
    speed_from_position: bool = False  # the speed was derived from the position (rig recording)


class Fit(NamedTuple):
    """The outcome: every parameter's value [SI], standard errors, hinge moments, residuals."""

    values: dict[str, float]  # fitted or held, SI
    base: dict[str, float]
    standard_errors: dict[str, float]  # SI, fitted parameters only
    not_determined: list[str]
    degenerate: list[str]
    hinge_moments: list[float]  # [N m] per recording
    hinge_errors: list[float]  # [N m]
    hinge_stiffnesses: list[float]  # [N m/rad] per recording (0 when not fitted)
    stiffness_errors: list[float]  # [N m/rad] (0 when not fitted)
    residuals: list[dict[str, float]]  # per recording, per signal, relative RMS
    residual: float  # RMS of the whole normalised residual
    evaluations: int
    #: parameters with a tolerance that the recordings barely narrow: their value is the
    #: tolerance's as much as the recordings' (:data:`PRIOR_DOMINATED`)
    from_tolerance: tuple[str, ...] = ()


def prepare(trace: Trace, source: str, params: Parameters) -> Recording:
    """Check a recording can commission (motion, length) and low-pass its signals."""
    duration = float(trace.time[-1] - trace.time[0])
    if duration < MIN_DURATION:
        raise InputError(
            source,
            f"cannot commission from {duration:.3g} s: a recording of at "
            f"least {MIN_DURATION:g} s of the standard test command is needed to "
            "determine inertias, viscous and friction",
        )
    speed_limit = params.spec.controller.speed_limit
    peak = float(np.max(np.abs(trace["speed"])))
    if peak < MIN_SPEED_SHARE * speed_limit:
        raise InputError(
            source,
            f"cannot commission: the motor barely moves (peak speed "
            f"{peak:.3g} rad/s, below {MIN_SPEED_SHARE:.0%} of the "
            f"{speed_limit:g} rad/s limit), so inertias, viscous, friction and the "
            "torque constant are not determined; record the standard test command "
            "(e.g. a 0.05 rad chirp, 0.5-10 Hz)",
            "speed",
        )
    rate = params.spec.controller.rate
    inputs = inputs_from_trace(trace, params)
    width_model = filter_width(rate)
    recording_rate = trace.sample_rate
    width = filter_width(recording_rate)
    instants = recorded_instants(
        trace.time, inputs.time, filter_lag(width_model, rate) - filter_lag(width, recording_rate)
    )
    current, position, speed = (
        low_pass(trace[name], width) for name in ("current", "position", "speed")
    )
    measured = (current, position, speed)
    mask = np.ones(trace.time.size, bool)
    mask[: round(STARTUP_SECONDS * recording_rate)] = False
    scales = np.array([max(float(np.sqrt(np.mean(m[mask] ** 2))), 1e-12) for m in measured])
    derived = speed_source_of(trace) == "position"
    return Recording(source, trace, inputs, instants, measured, scales, mask, derived)


class _Problem:
    """The residual function of the fit over a chosen set of free unknowns."""

    def __init__(
        self, recordings: list[Recording], params: Parameters, free: list[str], spring: bool
    ):
        self.recordings, self.params, self.free, self.spring = recordings, params, free, spring
        # under hysteresis a finer Monitor step than identification's: the commutation
        # events land on the step grid, which makes the residual jagged in the parameters
        # (2nd differences of the cost along a line: 4.6 % of it with 4 steps a period, 0.8 %
        # with 16), and the trust region of the fit collapsed on it; under PWM
        # identification's own step (fit_substeps)
        self.family = family_of(params)
        self.options = monitor.options(params)._replace(substeps=fit_substeps(params))
        self.faults = monitor_form(healthy_values(), params.spec.monitor.eccentricity_gain)
        self.width = filter_width(params.spec.controller.rate)
        m = params.spec.mechanical
        self.base_ratio = m.static_friction / m.dynamic_friction
        self.blocks = [int(r.mask.sum()) for r in recordings for _ in range(3)]
        # the plant the batched runs' unit rows are applied to (its other values: the set's)
        self.base = fine_plant(params.plant)
        self.evaluations = 0
        # the tolerances' prior rows (:func:`prior_widths`): none until _solve sets them
        self.prior = np.full(len(free), np.inf)
        self.prior_weight = 0.0
        self.scale = math.nan  # the fit's information scale, once _solve has solved it

    def prior_rows(self, x: np.ndarray) -> np.ndarray:
        """The prior's residual rows: weight x log factor / its width, one per free unknown
        with a tolerance (none without)."""
        given = np.isfinite(self.prior)
        return self.prior_weight * np.asarray(x[: len(self.free)])[given] / self.prior[given]

    def plant(self, factors: dict[str, float]) -> Plant:
        base = self.params.plant
        e, m = base.electrical, base.mechanical
        dynamic = m.dynamic_friction * factors["dynamic_friction"]
        electrical = e._replace(
            **{
                u.name: getattr(e, u.name) * factors[u.name]
                for u in UNKNOWNS
                if u.section == "electrical"
            }
        )
        mechanical = m._replace(
            **{
                u.name: getattr(m, u.name) * factors[u.name]
                for u in UNKNOWNS
                if u.section == "mechanical" and u.name != "static_friction"
            },
            static_friction=dynamic * self.base_ratio * factors["ratio"],
        )
        # unquantised feedback: a smooth residual for the finite-difference Jacobian
        return fine_plant(Plant(electrical, mechanical, base.controller, base.sensors))

    def factors(self, x: np.ndarray) -> dict[str, float]:
        out = {u.name: 1.0 for u in UNKNOWNS}
        out["ratio"] = 1.0  # of static/dynamic friction on the base set's ratio
        for name, value in zip(self.free, x):
            out[name] = math.exp(value)
        return out

    def hinges(self, x: np.ndarray) -> np.ndarray:
        """Each recording's constant hinge moment [N m]."""
        start = len(self.free)
        return HINGE_SCALE * np.asarray(x[start : start + len(self.recordings)])

    def springs(self, x: np.ndarray) -> np.ndarray:
        """Each recording's aerodynamic spring [N m/rad] (zeros when not fitted)."""
        if not self.spring:
            return np.zeros(len(self.recordings))
        return SPRING_SCALE * np.asarray(x[len(self.free) + len(self.recordings) :])

    def _residual(self, recording: Recording, outputs) -> list[np.ndarray]:
        """One recording's weighted residual parts from the Monitor's outputs."""
        current, position, speed = outputs
        if recording.speed_from_position:  # the same derivative as the recording's speed
            speed = derived_speed(
                recording.inputs.time, self.params.spec.mechanical.gear_ratio * position
            )
        model = [
            recording.instants.sample(low_pass(signal, self.width))
            for signal in (current, position, speed)
        ]
        return [
            ((model[s] - recording.measured[s]) / recording.scales[s])[recording.mask]
            for s in range(3)
        ]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        self.evaluations += 1
        plant = self.plant(self.factors(x))
        parts = []
        for recording, hinge, spring in zip(self.recordings, self.hinges(x), self.springs(x)):
            n = recording.inputs.time.size
            out = MonitorOutputs(np.empty(n), np.empty(n), np.empty(n), np.empty(n))
            drive = recording.inputs.drive(float(hinge))
            drive = drive._replace(load_stiffness=drive.load_stiffness + float(spring))
            self.family.simulate_monitor(drive, plant, self.faults, self.options, out)
            parts += self._residual(recording, (out.current, out.position, out.speed))
        return np.concatenate([*parts, self.prior_rows(x)])

    def batch(self, fun, points) -> list[np.ndarray]:
        """``least_squares``'s ``workers``: the residuals at every point of a finite-difference
        Jacobian, each recording's Monitor runs for all points in one parallel call. The same
        numbers as ``fun`` point by point (the same plant and drive per run), in a fraction of
        the time."""
        xs = [np.asarray(x, dtype=np.float64) for x in points]
        self.evaluations += len(xs)
        plants = [self.plant(self.factors(x)) for x in xs]
        hinges = [self.hinges(x) for x in xs]
        springs = [self.springs(x) for x in xs]
        row = np.asarray(self.faults, dtype=np.float64)
        parts: list[list[np.ndarray]] = [[] for _ in xs]
        for r, recording in enumerate(self.recordings):
            units = np.array(
                [
                    self.family.unit_row(p, float(h[r]), float(k[r]))
                    for p, h, k in zip(plants, hinges, springs)
                ]
            )
            n, m = recording.inputs.time.size, len(xs)
            current, position, speed = np.empty((m, n)), np.empty((m, n)), np.empty((m, n))
            self.family.simulate_units(
                row,
                units,
                recording.inputs.drive(),
                self.base,
                self.options,
                current,
                position,
                speed,
            )
            for j in range(m):
                parts[j] += self._residual(recording, (current[j], position[j], speed[j]))
        return [np.concatenate([*p, self.prior_rows(x)]) for p, x in zip(parts, xs)]


def _free_bounds(
    free: list[str], count: int, params: Parameters, spring: bool
) -> tuple[np.ndarray, np.ndarray]:
    by_name = {u.name: u for u in UNKNOWNS}
    m = params.spec.mechanical
    base_ratio = m.static_friction / m.dynamic_friction
    lower, upper = [], []
    for name in free:
        if name == "ratio":  # static >= dynamic, at most 3 x dynamic
            lower.append(math.log(1.0 / base_ratio))
            upper.append(math.log(3.0 / base_ratio))
        else:
            lower.append(math.log(by_name[name].lower))
            upper.append(math.log(by_name[name].upper))
    lower += [-HINGE_BOUND / HINGE_SCALE] * count
    upper += [HINGE_BOUND / HINGE_SCALE] * count
    if spring:
        lower += [SPRING_BOUNDS[0] / SPRING_SCALE] * count
        upper += [SPRING_BOUNDS[1] / SPRING_SCALE] * count
    return np.array(lower), np.array(upper)


def prior_widths(params: Parameters, free: list[str]) -> np.ndarray:
    """The prior's standard deviation of each free log factor: a build tolerance +-t read as
    uniform, ``t / sqrt(3)`` (the static friction's on its ratio to the dynamic); inf where
    the set gives no tolerance."""
    tolerances = params.spec.tolerances or {}
    return np.array(
        [
            tolerances.get("static_friction" if name == "ratio" else name, math.inf)
            / math.sqrt(3.0)
            for name in free
        ]
    )


def _solve(recordings, params, free, x0, spring, prior=None, prior_weight=0.0):
    """One fit from ``x0``; with ``prior`` (:func:`prior_widths`) and its weight, the maximum
    a posteriori one. Returns the problem, the result (its residual and Jacobian the
    recordings' alone), the covariance of the unknowns and the recordings' information."""
    problem = _Problem(recordings, params, free, spring)
    if prior is not None:
        problem.prior, problem.prior_weight = np.asarray(prior, float), float(prior_weight)
    lower, upper = _free_bounds(free, len(recordings), params, spring)
    with serial_blas():
        # a robust (soft L1) pass first, then the plain least squares whose Jacobian gives the
        # covariance: from the base set the plain pass alone stalled, on the commissioning
        # test's unit, in a valley of the inertia split and stiffness at 7 x the truth's cost
        start = least_squares(
            problem,
            np.clip(x0, lower, upper),
            bounds=(lower, upper),
            method="trf",
            diff_step=DIFF_STEP,
            x_scale=1.0,
            xtol=1e-8,
            ftol=1e-10,
            max_nfev=200,
            loss="soft_l1",
            f_scale=ROBUST_SCALE,
            workers=problem.batch,
        ).x
        result = least_squares(
            problem,
            start,
            bounds=(lower, upper),
            method="trf",
            diff_step=DIFF_STEP,
            x_scale=1.0,
            xtol=1e-8,
            ftol=1e-10,
            max_nfev=200,
            workers=problem.batch,
        )
        # the covariance on one BLAS thread too: the same numbers whatever the thread count
        data = result.fun.size - problem.prior_rows(result.x).size
        result.fun, result.jac = result.fun[:data], np.asarray(result.jac)[:data]
        jac = result.jac
        dof = max(result.fun.size - jac.shape[1], 1)
        s2 = float(result.fun @ result.fun) / dof
        information = jac.T @ jac
        # the residual variance times its correlation length: the recordings' information's
        # scale (and, under tolerances, the prior's weight in the next fit: _fit)
        problem.scale = s2 * correlation_length(result.fun, problem.blocks)
        posterior = information
        if np.isfinite(problem.prior).any():  # the prior's information in the same scale
            widths = np.full(jac.shape[1], np.inf)
            widths[: len(free)] = problem.prior
            posterior = information + np.diag(problem.scale / widths**2)
            cov = problem.scale * _scaled_inverse(posterior)
        else:
            cov = problem.scale * information_inverse(posterior)
    return problem, result, cov, information


def _scaled_inverse(posterior: np.ndarray) -> np.ndarray:
    """:func:`information_inverse` of the Jacobi-scaled posterior (unit diagonal), scaled
    back. Unscaled, its relative floor (1e-12 of the largest eigenvalue) read the prior's
    directions as blind: on a calibration-pwm unit (case 155) the recordings' information
    spans 0 (static friction) to 3e12 (back-EMF constant) against the prior's 0.7, so every
    variance came out infinite, the spring fitted at 2793 N m/rad (true 2788) was not kept
    and the commissioning without it was refused at 15 % of the current's RMS."""
    size = np.sqrt(np.diag(posterior))
    size = np.where(size > 0.0, size, 1.0)  # a column that changes nothing stays blind
    scale = np.outer(size, size)
    return information_inverse(posterior / scale) / scale


#: A spring is kept when the fit with it finds one of at least this many standard errors
#: [-] and this large [N m/rad] (the spring nuisance's load scale: 10 N m at the standard
#: command's 0.05 rad). Below, fitting it costs more than it gives: on the 200 robustness
#: units (no spring) a spring fitted in every unit took the 90 % intervals from 89.5 to 85 %
#: (backlash) and backlash within tolerance from 97 to 94.5 %.
SPRING_EVIDENCE = 5.0
SPRING_SIGNIFICANT = 200.0
#: The fit with the spring is tried when the one without it shows a spring
#: (:func:`spring_evidence`) of at least this many of its standard errors and half the
#: significant size: the projected step underestimates it (the other unknowns absorbed
#: part of it), measured 662 +- 221 N m/rad for a true 2000 (then fitted: 2017 +- 7), and
#: -10 +- 8 for none (fitted anyway: -16 +- 6, held).
SPRING_SCREEN = 2.0
SPRING_PROBE = 100.0  # [N m/rad] finite-difference step of the spring's column


def fit(recordings: list[Recording], params: Parameters, spring: bool | None = None) -> Fit:
    """Commission a unit from healthy recordings (module docstring); Fit with SI values.

    ``spring``: True fits each recording's aerodynamic spring beside its hinge moment,
    False holds it at 0, None (default) fits it when the fit without it shows one
    (:func:`spring_evidence`): a spring reads as a negative inertia at each frequency, so a
    unit commissioned under one without it is accepted with wrong values."""
    if spring is not None:
        return _fit(recordings, params, spring)[0]
    held, problem, result = _fit(recordings, params, False)
    estimate, error = spring_evidence(problem, result)
    held = held._replace(evaluations=held.evaluations + len(recordings) + 1)  # the screen's runs
    if not np.any(np.abs(estimate) > np.maximum(SPRING_SCREEN * error, SPRING_SIGNIFICANT / 2)):
        return held
    fitted = _fit(recordings, params, True)[0]
    fitted = fitted._replace(evaluations=fitted.evaluations + held.evaluations)
    size = np.abs(fitted.hinge_stiffnesses)
    limit = np.maximum(SPRING_EVIDENCE * np.asarray(fitted.stiffness_errors), SPRING_SIGNIFICANT)
    return fitted if np.any(size > limit) else held


def spring_evidence(problem: _Problem, result) -> tuple[np.ndarray, np.ndarray]:
    """Each recording's aerodynamic spring [N m/rad] as the fit held at 0 would see it, and
    its standard error: the Gauss-Newton step of the springs alone on the part of their
    residual columns the fitted unknowns cannot explain (their projection out of the fit's
    Jacobian), with the fit's residual variance and correlation length."""
    count = len(problem.recordings)
    probe = _Problem(problem.recordings, problem.params, problem.free, True)
    base = np.concatenate([result.x, np.zeros(count)])
    points = [base]
    for r in range(count):
        x = base.copy()
        x[len(result.x) + r] = SPRING_PROBE / SPRING_SCALE
        points.append(x)
    residuals = probe.batch(probe, points)
    columns = np.column_stack([(f - residuals[0]) / SPRING_PROBE for f in residuals[1:]])
    jac = np.asarray(result.jac)
    with serial_blas():
        explained = jac @ np.linalg.lstsq(jac, columns, rcond=None)[0]
        own = columns - explained
        step = -np.linalg.lstsq(own, residuals[0], rcond=None)[0]
        dof = max(residuals[0].size - jac.shape[1] - count, 1)
        s2 = float(residuals[0] @ residuals[0]) / dof
        cov = (
            s2 * correlation_length(residuals[0], problem.blocks) * information_inverse(own.T @ own)
        )
    return step, np.sqrt(np.maximum(np.diag(cov), 0.0))


#: [-] a parameter with a tolerance whose posterior standard error is above this share of
#: its prior's is set by the tolerance rather than by the recordings: the recordings narrow
#: its spread by less than a fifth of the prior's (reported apart, ``from_tolerance``).
PRIOR_DOMINATED = 0.9
#: The prior's weight in the first fit under tolerances, before the fit's own information
#: scale (residual variance times correlation length, :func:`_solve`) gives it (about a third of what they give on
#: robustness-pwm's commissioning recordings, 0.05-0.06): weak enough that the recordings
#: lead, strong enough that an unconstrained parameter stays near its base value.
PRIOR_START_WEIGHT = 0.02


def _fit(
    recordings: list[Recording], params: Parameters, spring: bool
) -> tuple[Fit, _Problem, object]:
    """The fit with the spring fitted or held (:func:`fit`); with its last problem and
    least-squares result."""
    free = [u.name for u in UNKNOWNS if u.name != "static_friction"] + ["ratio"]
    held: list[str] = []
    x0 = np.zeros(len(free) + len(recordings) * (2 if spring else 1))
    evaluations = 0
    tolerated = bool(params.spec.tolerances)
    weight = PRIOR_START_WEIGHT if tolerated else 0.0
    while True:
        widths = prior_widths(params, free)
        problem, result, cov, information = _solve(
            recordings, params, free, x0, spring, widths, weight
        )
        evaluations += problem.evaluations
        errors = np.sqrt(np.maximum(np.diag(cov)[: len(free)], 0.0))  # inf: not constrained
        # a parameter with a tolerance is never held: the tolerance bounds it
        errors = np.where(np.isfinite(widths), 0.0, errors)
        worst = int(np.argmax(errors)) if free else -1
        if free and errors[worst] > MAX_LOG_ERROR:
            name = free.pop(worst)
            held.append("static_friction" if name == "ratio" else name)
            x0 = np.delete(result.x, worst)
            continue
        break
    from_tolerance: tuple[str, ...] = ()
    if tolerated:
        problem, result, cov, information = _solve(
            recordings, params, free, result.x, spring, widths, math.sqrt(problem.scale)
        )
        evaluations += problem.evaluations
        errors = np.sqrt(np.maximum(np.diag(cov)[: len(free)], 0.0))
        from_tolerance = tuple(
            "static_friction" if n == "ratio" else n
            for n, e, w in zip(free, errors, widths)
            if math.isfinite(w) and e > PRIOR_DOMINATED * w
        )
    factors = problem.factors(result.x)
    plant = problem.plant(factors)
    values = {u.name: float(getattr(getattr(plant, u.section), u.name)) for u in UNKNOWNS}
    base = {u.name: float(getattr(getattr(params.plant, u.section), u.name)) for u in UNKNOWNS}
    standard_errors = {}
    for k, name in enumerate(free):
        target = "static_friction" if name == "ratio" else name
        log_error = math.sqrt(max(cov[k, k], 0.0))
        if name == "ratio":  # static = dynamic x ratio: both log errors add (correlation kept)
            j = free.index("dynamic_friction") if "dynamic_friction" in free else None
            variance = cov[k, k] + (cov[j, j] + 2 * cov[j, k] if j is not None else 0.0)
            log_error = math.sqrt(max(variance, 0.0))
        standard_errors[target] = values[target] * log_error
    degenerate = _weak_directions(free, information, cov)
    count = len(recordings)
    hinge_cov = np.diag(cov)[len(free) : len(free) + count]
    spring_cov = np.diag(cov)[len(free) + count :] if spring else np.zeros(count)
    residuals, parts = (
        [],
        np.split(result.fun, np.cumsum([3 * r.mask.sum() for r in recordings])[:-1]),
    )
    for _recording, part in zip(recordings, parts):
        per_signal = np.split(part, 3)
        residuals.append(
            {
                name: float(np.sqrt(np.mean(p**2)))
                for name, p in zip(("current", "position", "speed"), per_signal)
            }
        )
    return (
        Fit(
            values,
            base,
            standard_errors,
            held,
            degenerate,
            [float(h) for h in problem.hinges(result.x)],
            [float(HINGE_SCALE * math.sqrt(max(v, 0.0))) for v in hinge_cov],
            [float(k) for k in problem.springs(result.x)],
            [float(SPRING_SCALE * math.sqrt(max(v, 0.0))) for v in spring_cov],
            residuals,
            float(np.sqrt(np.mean(result.fun**2))),
            evaluations,
            from_tolerance,
        ),
        problem,
        result,
    )


def _weak_directions(free: list[str], information: np.ndarray, cov: np.ndarray) -> list[str]:
    """The least constrained combination of the fitted parameters, in words, if it is weak."""
    n = len(free)
    if n < 2:
        return []
    block = information[:n, :n]
    eigenvalues, vectors = np.linalg.eigh(block)
    v = vectors[:, 0]
    spread = float(np.sqrt(max(v @ cov[:n, :n] @ v, 0.0)))
    if spread <= MAX_LOG_ERROR / 2:
        return []
    order = np.argsort(-np.abs(v))[:4]
    terms = ", ".join(
        f"{'+' if v[i] > 0 else '-'}{abs(v[i]):.2f} {free[i]}" for i in order if abs(v[i]) > 0.1
    )
    return [f"log-factors along ({terms}) are determined to {spread:.1%} only (1 sigma)"]


def check_explained(fit_result: Fit, recordings: list[Recording]) -> None:
    """Refuse a commissioning whose Monitor does not explain a recording (exit 2)."""
    for recording, residual in zip(recordings, fit_result.residuals):
        if residual["current"] > MAX_CURRENT_RESIDUAL:
            raise InputError(
                recording.source,
                "cannot commission: after the fit the healthy Monitor still misses "
                f"{past_limit(residual['current'], MAX_CURRENT_RESIDUAL, '.0%')} of the "
                "current's RMS "
                f"(at most {MAX_CURRENT_RESIDUAL:.0%}); is the unit healthy, the "
                "recording of this actuator, and the column map right?",
                "current",
            )


def _drive_note(base: Parameters) -> list[str]:
    """The change line saying that a PWM drive's gains were written out (none when the base
    set gives them all, or the drive is a hysteresis regulator)."""
    from ..config.parameters import GAIN_KEYS, drive_gains

    loop = base.spec.drive
    if loop.regulator != "pwm" or all(getattr(loop, k) is not None for k in GAIN_KEYS):
        return []
    kp, ki, kf = drive_gains(base.spec)
    return [
        f"drive: gains written out as the drive has them (proportional_gain {kp:.6g} V/A, "
        f"integral_gain {ki:.6g} V/(A s), feedforward_gain {kf:.6g} V s/rad, from the base "
        "set's bandwidth and winding): the commissioned winding does not retune the drive."
    ]


def unit_set(
    base: Parameters,
    fit_result: Fit,
    recordings: list[Recording],
    name: str,
    date: str,
    columns: str | None = None,
) -> str:
    """The commissioned unit as a complete parameter-set YAML text (checked to load)."""
    import hashlib

    import yaml

    from .. import __version__
    from ..config.parameters import ParameterFile, fixed_drive_spec
    from ..config.yamlfile import parse_mapping

    spec = fixed_drive_spec(base)
    for u in UNKNOWNS:
        spec[u.section][u.name] = float(fit_result.values[u.name])
    fitted = {
        u.name: {
            "value": fit_result.values[u.name],
            "base": fit_result.base[u.name],
            "standard_error": reported_error(
                u.name, fit_result.values[u.name], fit_result.standard_errors[u.name]
            ),
        }
        for u in UNKNOWNS
        if u.name in fit_result.standard_errors
    }
    sources = [
        {
            "file": str(Path(r.source).resolve()) if Path(r.source).is_file() else r.source,
            "sha256": hashlib.sha256(Path(r.source).read_bytes()).hexdigest()
            if Path(r.source).is_file()
            else "",
            "columns": str(Path(columns).resolve()) if columns is not None else None,
            "hinge_moment": h,
            "hinge_moment_standard_error": reported_error("hinge_moment", h, e),
            **(
                {"hinge_stiffness": k, "hinge_stiffness_standard_error": k_error} if k_error else {}
            ),
            "residual": res,
            "phase_identity": (r.trace.metadata or {}).get("phase_identity"),
        }
        for r, h, e, k, k_error, res in zip(
            recordings,
            fit_result.hinge_moments,
            fit_result.hinge_errors,
            fit_result.hinge_stiffnesses,
            fit_result.stiffness_errors,
            fit_result.residuals,
        )
    ]
    spec.update(
        name=name,
        description=f"Unit commissioned on {date} from {len(recordings)} healthy recording(s); "
        f"base set '{base.spec.name}'.",
        source=f"emaprog commission {__version__}: the base set's values, with those the "
        "recordings determine fitted by bounded least squares of the healthy Monitor "
        "Model (see commissioning).",
        changes=[
            *base.spec.changes,
            f"commissioned on {date}: "
            + ", ".join(f"{k} x{fit_result.values[k] / fit_result.base[k]:.3f}" for k in fitted)
            + (
                f"; held at base: {', '.join(fit_result.not_determined)}"
                if fit_result.not_determined
                else ""
            )
            + (
                f"; within the build tolerances, barely narrowed by the recordings: "
                f"{', '.join(fit_result.from_tolerance)}"
                if fit_result.from_tolerance
                else ""
            ),
            *_drive_note(base),
        ],
        commissioning={
            "date": date,
            "emaprog_version": __version__,
            "base": base.source_file,
            "recordings": sources,
            "fitted": fitted,
            "not_determined": fit_result.not_determined,
            "degenerate": fit_result.degenerate,
            "residual": fit_result.residual,
            **(
                {
                    "tolerances": dict(base.spec.tolerances),
                    "from_tolerance": list(fit_result.from_tolerance),
                }
                if base.spec.tolerances
                else {}
            ),
        },
    )
    text = yaml.safe_dump(spec, sort_keys=False, width=100)
    ParameterFile.model_validate(parse_mapping(text, name))  # loadable, or an internal error
    return text
