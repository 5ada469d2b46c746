"""Identify fault magnitudes in a trace: GA over the Monitor Model, then a local polish."""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np
from scipy.optimize import minimize as local_minimize

from .. import progress
from ..errors import InputError
from ..models.common import Inputs
from ..numerics import DEFAULT, Numerics
from ..parameters import Parameters
from ..scenario import IdentifySettings
from ..storage import Trace
from .ga import GAOptions, minimize
from .objective import Objective, nominal_discrepancy

REFINE_EVALUATIONS = 400  # budget of the local search (Powell) after the GA


class Identification(NamedTuple):
    estimate: dict[str, float]  # final (refined when it improved on the GA)
    ga_estimate: dict[str, float]
    fitness: float
    ga_fitness: float
    evaluations: int
    generations: int
    stopped_by: str
    refined: bool
    elapsed_s: float
    logbook: list[dict]
    objective: Objective


def check_sampling(trace: Trace, params: Parameters, source: str) -> None:
    rate = params.spec.controller.rate
    if abs(trace.sample_rate - rate) > 1e-6 * rate:
        raise InputError(source, f"trace is sampled at {trace.sample_rate:.6g} Hz but the parameter "
                         f"set's controller runs at {rate:.6g} Hz; they must match", "time")


def identify_trace(trace: Trace, inputs: Inputs, params: Parameters, settings: IdentifySettings,
                   numerics: Numerics = DEFAULT, show_progress: bool = True) -> Identification:
    """Run the GA (and optional refinement) on one trace; nothing is written."""
    start = time.perf_counter()
    discrepancy = nominal_discrepancy(inputs, params, numerics) if settings.nominal_correction else None
    objective = Objective(trace, inputs, params, settings, numerics, discrepancy)
    ga = settings.ga
    options = GAOptions(population=ga.population, generations=ga.generations,
                        crossover=ga.crossover, mutation=ga.mutation)
    healthy = objective.healthy_genes()
    with progress.task("identify", ga.generations, show_progress) as advance:

        def on_generation(gen: int, best: float) -> None:
            if gen:
                advance(1, best=f"{best:.3e}")

        result = minimize(objective, objective.dims, options, seed=ga.seed,
                          circular=objective.circular, initial=healthy[None],
                          on_generation=on_generation)
    best, best_fitness, refined = result.best, result.fitness, False
    if settings.refine:
        bounds = [(-0.5, 1.5) if c else (0.0, 1.0) for c in objective.circular]
        polish = local_minimize(lambda g: float(objective(g[None])[0]), best, method="Powell",
                                bounds=bounds,
                                options={"maxfev": REFINE_EVALUATIONS, "xtol": 1e-4, "ftol": 1e-6})
        if polish.fun < best_fitness:
            best, best_fitness, refined = np.asarray(polish.x), float(polish.fun), True
    return Identification(
        estimate=objective.values(best), ga_estimate=objective.values(result.best),
        fitness=best_fitness, ga_fitness=result.fitness, evaluations=objective.evaluations,
        generations=result.generations, stopped_by=result.stopped_by, refined=refined,
        elapsed_s=time.perf_counter() - start, logbook=list(result.logbook), objective=objective,
    )
