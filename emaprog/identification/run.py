"""Identify fault magnitudes in a trace: GA over the Monitor Model, then a local polish."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from scipy.optimize import least_squares, minimize_scalar
from scipy.optimize import minimize as local_minimize

from .. import progress
from ..config.parameters import Parameters
from ..config.scenario import IdentifySettings
from ..errors import InputError
from ..faults import CATALOGUE, FAULTS, PHASE_FAULTS, incipient_thresholds
from ..io.storage import Trace
from ..models.common import Inputs
from ..numerics import DEFAULT, Numerics, serial_blas
from .confidence import (
    MISMATCH_RATIO,
    Confidence,
    assess,
    basis_of,
    is_twin,
    judging_basis,
    uninformative,
)
from .echo import echo_errors, off_calibration
from .ga import GAOptions, minimize
from .objective import (
    NO_CORRECTION,
    Correction,
    Objective,
    ResidualRecording,
    fine_plant,
    recording_correction,
    reference_correction,
)

REFINE_EVALUATIONS = 400  # budget of the Powell polish after the GA [Monitor runs]
#: Steps of the least-squares polish (each one Monitor run and, for its Jacobian, a batch of
#: one run per gene).
REFINE_STEPS = 30
#: Finite-difference step of the least-squares polish's Jacobian [polish coordinates, of 1].
JACOBIAN_STEP = 1e-3
#: The GA's (population, generations) when the settings leave them out: 32 x 20 in front of
#: the least-squares polish (docs/explanation/validation-and-speed.md: as accurate as 64 x 40 on the campaigns, a quarter of the
#: Monitor runs), :data:`LARGE_GA` for a recording slower than :data:`LOW_RATE` [Hz], where
#: the aliased commutation structure makes the search harder, and for a unit in the form
#: of a real actuator (a PWM drive or a logger's chain), whose switched drive makes the
#: landscape rougher. Measured at 1 kHz (``benchmarks/rates.py``, 10 regression cases):
#: 32 x 20 within tolerance on the short circuit in 80 % of cases and on zeta in 60 %,
#: 64 x 40 in 90 % and 100 %; at 2 kHz and above both budgets are level. On the form
#: (``campaigns/form/pwm-exact-unloaded.yaml``, 40 commissioned units): 32 x 20 left the
#: backlash within tolerance in 72 % of the units (bias -34 urad), many fits in another
#: basin than the truth's (14 of 40 above 20 x their noise floor on a Monitor variant
#: with another dead-time law, 6 with 64 x 40); 64 x 40: 98 % (bias -0.4 urad), 5 above 20 x.
DEFAULT_GA = (GAOptions().population, GAOptions().generations)
LARGE_GA = (64, 40)
LOW_RATE = 2500.0


def ga_budget(ga, sample_rate: float, hysteresis_form: bool = True) -> tuple[int, int]:
    """(population, generations) of ``identify.ga`` for a recording at ``sample_rate`` [Hz]
    of a unit whose set has the paper's form (``hysteresis_form``) or not."""
    small = sample_rate >= LOW_RATE and hysteresis_form
    population, generations = DEFAULT_GA if small else LARGE_GA
    return (
        population if ga.population is None else ga.population,
        generations if ga.generations is None else ga.generations,
    )


#: Independent GA runs at most on a unit in the form of a real actuator (``identify.ga.runs``
#: omitted; 1 on the paper's form). On ``campaigns/form/pwm-exact-loaded.yaml`` single 64 x 40
#: runs of one case from four seeds ended at 30, 17, 24 and 25 x the noise floor and another
#: case's at 27, 14, 23 and 25 x: different basins, and the lowest fit was the accurate one
#: (backlash within 3 and 25 urad, friction within 1-5 %, where the others missed by up to
#: 90 urad and 17 %); the least-squares polish started from the truth reached 17 and 13 x.
FORM_RUNS = 4
#: [-] two runs whose polished fits are this close (relative) found the same minimum: stop.
#: Not 2 %: on ``campaigns/calibration-pwm.yaml`` the fit is flat along the friction, and
#: polished runs within 2 % of the best fit read the friction a median 1.8 points apart
#: on the 53 units that had two such runs (one unit's: fits 1.753 and 1.765e-4, friction
#: -6.0 and +5.1 %). The 88 of its 400 units that had stopped at 2 % after two or three
#: runs were within tolerance in friction 75 % and backlash 78 %, made to 0.1 % 77 and
#: 82 % (82 of them then made all four runs);
#: over the 400, friction 85.25 -> 85.75 %, backlash 87.25 -> 88 %, short circuit and zeta
#: 0.25-0.5 points up, the identification 27.9 -> 31.6 s (mean, a slow 2-core machine).
#: On robustness-pwm's 28 such units friction fell (85.5 -> 81.5 % of the 200 within),
#: backlash rose (83.5 -> 84.5 %): the lowest of equally good fits is not the truer friction.
RUNS_AGREE = 0.001


def ga_runs(ga, hysteresis_form: bool = True) -> int:
    """The most independent GA runs of ``identify.ga`` for a unit of the paper's form
    (``hysteresis_form``) or not."""
    if ga.runs is not None:
        return ga.runs
    return 1 if hysteresis_form else FORM_RUNS


def run_seed(seed: int, run: int) -> int:
    """The GA seed of run ``run`` (0: ``seed`` itself), reproducible from ``seed`` alone."""
    if run == 0:
        return seed
    return int(np.random.SeedSequence([seed, run]).generate_state(1)[0])


def agreed(fits: list[float]) -> bool:
    """Whether the two best of the runs' polished fits are within :data:`RUNS_AGREE`."""
    if len(fits) < 2:
        return False
    first, second = sorted(fits)[:2]
    return second <= first * (1.0 + RUNS_AGREE)


class Identification(NamedTuple):
    estimate: dict[str, float]  # final (refined when it improved on the GA)
    ga_estimate: dict[str, float]
    fitness: float
    ga_fitness: float
    evaluations: int
    generations: int
    stopped_by: str
    refined: bool
    runs: int  # independent GA runs made (the best one's GA and polish are reported)
    cleared: bool  # the polish from :func:`cleared_start` found the lowest fit
    position_play: bool  # the play was read again from the position (:func:`play_from_position`)
    ga_seed: int  # the seed of that run (:func:`run_seed`)
    elapsed_s: float
    logbook: list[dict]
    objective: Objective
    confidence: Confidence


#: [Hz] slowest recording emaprog identifies from: below it the 1 ms error filter holds a
#: single sample and the commutation effects the faults show through are not resolved.
MIN_RATE = 1000.0


def check_sampling(trace: Trace, source: str) -> None:
    """A trace at any rate from :data:`MIN_RATE` up is fine; slower ones are refused."""
    if trace.sample_rate < MIN_RATE * (1.0 - 1e-6):
        raise InputError(
            source,
            f"trace is sampled at {trace.sample_rate:.6g} Hz; identification "
            f"needs at least {MIN_RATE:g} Hz (the error's 1 ms filter and the "
            "commutation effects the faults show through)",
            "time",
        )


class PolishCoordinates:
    """Coordinates of the local polish: the genes, but eccentricity in the plane.

    Near the optimum the current moves about linearly with the eccentricity
    vector ``(zeta cos phi, zeta sin phi)``, so in those Cartesian coordinates
    the error is a round bowl, while in (zeta, phi) it is a curved valley (and
    phi is undefined at zeta = 0) that a coordinate search crawls along. The
    polish therefore works on ``(x, y) = z (cos phi, sin phi)`` with ``z`` the
    normalised zeta gene, each in [-1, 1]; the other genes are unchanged.
    """

    def __init__(self, objective: Objective):
        names = [g.quantity for g in objective.genes]
        polar = [tuple(q.name for q in f.quantities) for f in CATALOGUE if f.layout == "polar"]
        self.pair = next(((names.index(m), names.index(a)) for m, a in polar if m in names), None)
        self.bounds = [
            (-1.0, 1.0) if self.pair and j in self.pair else (0.0, 1.0) for j in range(len(names))
        ]

    def coordinates(self, genes: np.ndarray) -> np.ndarray:
        u = np.array(genes, float)
        if self.pair:
            z, p = self.pair
            angle = 2.0 * np.pi * genes[p]
            u[z], u[p] = genes[z] * np.cos(angle), genes[z] * np.sin(angle)
        return u

    def genes(self, u: np.ndarray) -> np.ndarray:
        genes = np.array(u, float)
        if self.pair:
            z, p = self.pair
            genes[z] = min(1.0, float(np.hypot(u[z], u[p])))
            genes[p] = (np.arctan2(u[p], u[z]) / (2.0 * np.pi)) % 1.0
        return genes


def single_phase_starts(objective: Objective, genes: np.ndarray) -> list[np.ndarray]:
    """The GA's best with a per-phase fault moved onto one phase: further starts for the
    polish, one per estimated per-phase fault that is spread over phases.

    A short circuit on one phase and a smaller one spread over all three move
    the equivalent current alike on average (the sector-to-sector difference
    is what tells them apart), so the GA often ends in the spread valley and a
    local search from there does not climb out. The candidates clear every
    phase but one, which keeps its own fraction or carries the sum of all
    three; every phase is tried (the worst phase of a spread estimate is not
    always the shorted one: measured on the robustness campaign, a 9 % short on
    B estimated as 5 % on A and 3.5 % on B), and each fault's best candidate of the
    six is returned. Empty when no per-phase fault is estimated or each is already on
    one phase.
    """
    values = objective.values(genes)
    estimated = {g.quantity for g in objective.genes}
    starts = []
    for fault in PHASE_FAULTS:
        phases = [q.name for q in FAULTS[fault].quantities]
        fractions = {name: values[name] for name in phases}
        if phases[0] not in estimated or sum(v > 0 for v in fractions.values()) <= 1:
            continue
        candidates = []
        for phase in phases:
            for level in {fractions[phase], sum(fractions.values())}:
                moved = {**values, **{name: 0.0 for name in phases}, phase: level}
                candidates.append(objective.genes_for(moved))
        fitness = objective(np.array(candidates))
        starts.append(candidates[int(np.argmin(fitness))])
    return starts


def _powell(
    objective: Objective, plane: PolishCoordinates, origin: np.ndarray
) -> tuple[np.ndarray, float]:
    found = local_minimize(
        lambda u: float(objective(plane.genes(u)[None])[0]),
        plane.coordinates(origin),
        method="Powell",
        bounds=plane.bounds,
        options={"maxfev": REFINE_EVALUATIONS, "xtol": 1e-4, "ftol": 1e-6},
    )
    return plane.genes(found.x), float(found.fun)


def _least_squares(
    objective: Objective, plane: PolishCoordinates, origin: np.ndarray
) -> tuple[np.ndarray, float]:
    """Trust-region least squares on the residual vector, its Jacobian one batch per step."""
    lower = np.array([b[0] for b in plane.bounds])
    upper = np.array([b[1] for b in plane.bounds])
    plant = fine_plant(objective.params.plant)
    start = np.clip(plane.coordinates(origin), lower, upper)
    last: dict = {}

    def fun(u: np.ndarray) -> np.ndarray:
        key = u.tobytes()
        if key not in last:
            last.clear()
            last[key] = objective.residuals(plane.genes(u)[None], plant)[0]
        return last[key]

    def jac(u: np.ndarray) -> np.ndarray:
        base = fun(u)
        steps = np.where(u + JACOBIAN_STEP <= upper, JACOBIAN_STEP, -JACOBIAN_STEP)
        shifted = u[None, :] + np.diag(steps)
        moved = objective.residuals(np.array([plane.genes(x) for x in shifted]), plant)
        return ((moved - base[None, :]) / steps[:, None]).T

    with serial_blas():
        found = least_squares(
            fun,
            start,
            jac=jac,
            bounds=(lower, upper),
            method="trf",
            x_scale=1.0,
            xtol=1e-6,
            ftol=1e-8,
            max_nfev=REFINE_STEPS,
        )
    genes = plane.genes(found.x)
    return genes, float(objective(genes[None])[0])  # with the real ADC


POLISHERS = {"powell": _powell, "least_squares": _least_squares}


def polish(
    objective: Objective, start: np.ndarray, fitness: float, method: str = "least_squares"
) -> tuple[np.ndarray, float, bool]:
    """The local search after a global one, in :class:`PolishCoordinates`: ``powell``
    (bounded Powell, one Monitor run at a time) or ``least_squares`` (trust-region
    least squares on the residual vector, the Jacobian in one batch per step); from
    ``start``, then from the best single-phase start of the polished estimate.

    Returns the best genes, their fitness and whether the polish improved on ``start``.
    """
    plane = PolishCoordinates(objective)
    best, best_fitness, refined = start, fitness, False
    for stage in range(2):
        # stage 1: the single-phase starts from the polished estimate (its other faults fitted)
        for origin in [best] if stage == 0 else single_phase_starts(objective, best):
            genes, value = POLISHERS[method](objective, plane, origin)
            if value < best_fitness:
                best, best_fitness, refined = genes, value, True
    return best, best_fitness, refined


def cleared_start(
    objective: Objective, genes: np.ndarray, incipient: dict[str, float]
) -> np.ndarray | None:
    """The estimate with the faults it does not show cleared: a start for one more polish.

    Every fault magnitude whose own deviation from healthy stays under its fault's
    incipient threshold (``incipient``, fault name -> severity) is set to healthy, the
    other quantities kept; None when no such magnitude is away from healthy. A shorted
    fraction, a zeta or a play cannot go below healthy, so on a unit of another form than
    the Monitor's the search
    gives the model's mismatch small spurious faults (shorted fractions of 0.5-3 %, zeta of
    1-4 %) that trade against the faults present: on robustness-pwm's healthy units they
    read the friction 3 % low (median) and up to 10 %. The polish alone does not leave
    that basin; from this start it often reaches a lower fit (docs/explanation/validation-and-speed.md,
    "Faults the estimate does not show"). Used on a unit of another form than the paper's:
    on the paper's form the search's answer is within tolerance already and the intervals'
    laws are calibrated without this polish.
    """
    values = objective.values(genes)
    estimated = {g.quantity for g in objective.genes}
    moved = dict(values)
    for fault in CATALOGUE:
        for q in fault.magnitudes:
            deviation = abs(values[q.name] - q.healthy)
            if q.name in estimated and 0.0 < deviation < incipient[fault.name]:
                moved[q.name] = q.healthy
    return None if moved == values else objective.genes_for(moved)


#: [-] The surface position's weight beside the current's (1) when the play is read again
#: from it on a unit of another form (:func:`play_from_position`), the current's weighted
#: error left at the size of the position's over the play's range.
PLAY_POSITION_WEIGHT = 300.0
#: Candidate plays of that reading, evenly over the play's bounds (one batch), before the
#: bounded scalar search between the best one's neighbours.
PLAY_GRID = 41


def form_refinement(settings: IdentifySettings, params: Parameters) -> bool:
    """Whether an identification ends with the steps for a unit of another form than the
    hysteresis drive with an ideal chain - the polish from the cleared start
    (:func:`cleared_start`) and the play read from the position (:func:`play_from_position`)
    -: under ``identify.refine`` on such a set; the echo twin follows the same rule."""
    return settings.refine and not params.hysteresis_form


def play_from_position(objective: Objective, genes: np.ndarray) -> np.ndarray | None:
    """The estimate with its play read again where the play shows: in the surface position.

    Every other quantity is held at ``genes`` (the current's answer); the play minimises the
    current's error plus the position's at :data:`PLAY_POSITION_WEIGHT` (about its mean, so a
    logger's position zero is not read as a fault): :data:`PLAY_GRID` plays in one batch over
    the bounds, then a bounded Brent search between the best one's neighbours. None when
    the play is not estimated.

    Why only the play: through the current a play shows only by the load's impacts at the
    reversals, which a PWM drive's current loop and a logger's filters blur; in the position
    it is lost motion. A fit of every quantity to the position too reads the play within
    tolerance but moves the friction on a real friction's (LuGre, Stribeck) reversals,
    which the Monitor's dry friction cannot follow (docs/explanation/validation-and-speed.md,
    "The surface position in the error").
    """
    names = [g.quantity for g in objective.genes]
    if "backlash" not in names:
        return None
    j = names.index("backlash")
    seen = objective.reweighted((1.0, PLAY_POSITION_WEIGHT, 0.0))
    grid = np.linspace(0.0, 1.0, PLAY_GRID)
    rows = np.tile(np.asarray(genes, float), (PLAY_GRID, 1))
    rows[:, j] = grid
    values = seen(rows)
    k = int(np.argmin(values))

    def fitness(x: float) -> float:
        row = rows[k].copy()
        row[j] = x
        return float(seen(row[None])[0])

    low, high = grid[max(k - 1, 0)], grid[min(k + 1, PLAY_GRID - 1)]
    found = minimize_scalar(fitness, bounds=(low, high), method="bounded")
    out = rows[k].copy()
    if found.fun < values[k]:
        out[j] = found.x
    objective.evaluations += seen.evaluations
    return out


def mean_correction(chosen: Sequence[Correction]) -> Correction:
    """The mean of several commissioning recordings' residuals on the trace's grid.

    Each residual is the model's form error under that recording's load plus its noise; an
    inspection is made under a load of its own. The mean keeps what the recordings share,
    halves the noise of two, and lies nearer an inspection's load between theirs (the rig
    workflow commissions at 20 and 40 N m and inspects at 30) than either recording.
    Measured on robustness-pwm's first 40 units, each commissioned from two recordings
    under loads of their own (2026-12-07), against the first recording's residual alone:
    friction's median error 1.9 -> 1.0 %, short circuit's p95 0.029 -> 0.023, fits 15.7 ->
    12.9 x the noise floor (median); zeta's p95 0.030 -> 0.040, all within tolerance.
    """
    if len(chosen) == 1:
        return chosen[0]
    signals = [c.signals for c in chosen]
    assert all(s is not None for s in signals)  # recording corrections carry their signals
    mean = {
        name: np.mean([s[name] for s in signals if s is not None], axis=0)
        for name in signals[0] or {}
    }
    return Correction(
        "recording",
        f"mean of the residuals of {len(chosen)} commissioning recordings: "
        + "; ".join(c.note for c in chosen),
        mean,
        on_grid=False,
    )


def choose_correction(
    trace: Trace,
    inputs: Inputs,
    params: Parameters,
    settings: IdentifySettings,
    numerics: Numerics = DEFAULT,
    recordings: Sequence[ResidualRecording | str] = (),
) -> Correction:
    """The nominal-discrepancy correction ``identify.nominal_correction`` asks for.

    ``recordings``: the unit's commissioning recordings' residuals (or, for one that
    cannot be read, why); ``recording`` applies the mean of the residuals of those whose
    command and sample grid the trace repeats (:func:`mean_correction`), else falls back to
    ``reference`` and says why.
    """
    if settings.nominal_correction == "none":
        return NO_CORRECTION
    if settings.nominal_correction == "recording":
        reasons, chosen = [], []
        for recording in recordings:
            found = (
                recording if isinstance(recording, str) else recording_correction(trace, recording)
            )
            if isinstance(found, Correction):
                chosen.append(found)
            else:
                reasons.append(found)
        if chosen:
            return mean_correction(chosen)
        why = "; ".join(reasons) or "the parameter set carries no commissioning recording"
        return reference_correction(
            inputs, params, numerics, f"reference (recording asked, not applicable: {why})"
        )
    return reference_correction(inputs, params, numerics)


def identify_trace(
    trace: Trace,
    inputs: Inputs,
    params: Parameters,
    settings: IdentifySettings,
    numerics: Numerics = DEFAULT,
    show_progress: bool = True,
    recordings: Sequence[ResidualRecording | str] = (),
    commissioned: bool | None = None,
) -> Identification:
    """Run the GA (and optional refinement) on one trace; nothing is written.

    ``commissioned``: whether ``params`` was fitted to the unit that made the trace
    (default: the set carries a ``commissioning`` section); it chooses the intervals'
    model-error laws when the trace is not a twin experiment."""
    start = time.perf_counter()
    correction = choose_correction(trace, inputs, params, settings, numerics, recordings)
    objective = Objective(trace, inputs, params, settings, numerics, correction)
    ga = settings.ga
    population, generations = ga_budget(ga, trace.sample_rate, params.hysteresis_form)
    options = GAOptions(
        population=population,
        generations=generations,
        crossover=ga.crossover,
        mutation=ga.mutation,
        strategy=ga.strategy,
    )
    healthy = objective.healthy_genes()
    most = ga_runs(ga, params.hysteresis_form)
    chosen, fits = None, []
    with progress.task("identify", generations * most, show_progress) as advance:

        def on_generation(gen: int, best: float) -> None:
            if gen:
                advance(1, best=f"{best:.3e}")

        for run in range(most):
            seed = run_seed(ga.seed, run)
            result = minimize(
                objective,
                objective.dims,
                options,
                seed=seed,
                circular=objective.circular,
                initial=healthy[None],
                on_generation=on_generation,
            )
            best, best_fitness, refined = result.best, result.fitness, False
            if settings.refine:
                best, best_fitness, refined = polish(
                    objective, result.best, result.fitness, settings.polish
                )
            fits.append(best_fitness)
            if chosen is None or best_fitness < chosen[2]:
                chosen = (result, best, best_fitness, refined, seed)
            if agreed(fits):
                break
    assert chosen is not None  # most >= 1
    result, best, best_fitness, refined, chosen_seed = chosen
    cleared = False
    position_play = False
    if form_refinement(settings, params):
        origin = cleared_start(objective, best, incipient_thresholds(params.spec.health))
        if origin is not None:
            genes, value, _ = polish(
                objective, origin, float(objective(origin[None])[0]), settings.polish
            )
            if value < best_fitness:
                best, best_fitness, refined, cleared = genes, value, True, True
        reread = play_from_position(objective, best)
        if reread is not None:
            best, best_fitness, position_play = reread, float(objective(reread[None])[0]), True
    estimate = objective.values(best)
    if commissioned is None:
        commissioned = params.spec.commissioning is not None
    twin = is_twin(trace, params)
    angle = objective.inputs.motor_angle is not None
    own = basis_of(twin, commissioned, params.hysteresis_form, angle)
    basis = judging_basis(objective, trace, best_fitness, own)

    def judged(echo: dict | None = None) -> Confidence:
        return assess(
            objective,
            trace,
            estimate,
            best_fitness,
            settings.estimate,
            params.spec.health,
            twin=twin,
            basis=basis,
            echo=echo,
        )

    confidence = judged()
    reasons = off_calibration(
        trace, confidence.floor.sigma, confidence.floor.ratio, MISMATCH_RATIO[basis]
    )
    if reasons and uninformative(objective, trace, confidence.floor) is None:
        errors = echo_errors(objective, trace, estimate, settings, confidence.floor.sigma, numerics)
        confidence = judged({"reasons": reasons, "errors": errors})
    if basis != own:
        confidence = confidence._replace(past_limit_of=own)
    return Identification(
        estimate=estimate,
        ga_estimate=objective.values(result.best),
        fitness=best_fitness,
        ga_fitness=result.fitness,
        evaluations=objective.evaluations,
        generations=result.generations,
        stopped_by=result.stopped_by,
        refined=refined,
        runs=len(fits),
        cleared=cleared,
        position_play=position_play,
        ga_seed=chosen_seed,
        elapsed_s=time.perf_counter() - start,
        logbook=list(result.logbook),
        objective=objective,
        confidence=confidence,
    )
