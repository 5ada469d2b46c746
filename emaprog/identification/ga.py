"""A bounded real-coded genetic algorithm on DEAP, evaluated one generation per call.

Genes live in the unit box [0, 1]^d. Two strategies (``GAOptions.strategy``):

* ``numpy``: a generational GA with elitism whose operators are written here
  (tournament, BLX-alpha crossover, decaying Gaussian mutation; a gene flagged
  *circular*, an angle, wraps around instead of stopping at its bounds); every
  draw comes from one ``numpy.random.Generator`` seeded by the caller, and DEAP
  supplies the individuals, hall of fame, statistics and logbook;
* ``deap``: DEAP's own toolbox and the loop of ``algorithms.eaMuPlusLambda``
  (``varOr``, then mu of parents + offspring by ``selTournament``) with
  ``cxSimulatedBinaryBounded`` and ``mutPolynomialBounded``, written out so that each
  generation's new individuals go to the batched evaluator in one call and progress
  is reported; circular genes stay within [0, 1] like the others (the polish works
  in the plane). DEAP's operators draw from their module's ``random``; the run calls
  copies of them whose ``random`` is a :class:`random.Random` of its own, seeded by the
  caller (:func:`_drawing_from`): the global :mod:`random` is never touched.

Both start from the same Latin hypercube and spend ``population x (generations
+ 1)`` evaluations at most.
"""

from __future__ import annotations

import random
import types
from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np
from deap import algorithms, base, creator, tools

# DEAP's creator registers classes module-wide: create them once, at import.
if not hasattr(creator, "FaultFitness"):
    creator.create("FaultFitness", base.Fitness, weights=(-1.0,))
if not hasattr(creator, "FaultCandidate"):
    creator.create("FaultCandidate", list, fitness=creator.FaultFitness)

BatchFitness = Callable[[np.ndarray], np.ndarray]
"""Maps an (m, d) array of genes in [0, 1] to m fitness values (lower is better)."""


class GAOptions(NamedTuple):
    population: int = 32
    generations: int = 20
    crossover: float = 0.7  # [-] probability that a pair is recombined
    mutation: float = 0.2  # [-] probability that an individual is mutated
    tournament: int = 3
    elite: int = 2  # best individuals copied unchanged into the next generation
    blend: float = 0.3  # BLX-alpha: children drawn in the parents' box widened by alpha
    sigma_start: float = 0.15  # [-] Gaussian mutation step (fraction of the range), first gen
    sigma_end: float = 0.02  # [-] ... last generation (geometric decay)
    patience: int = 12  # generations without relative improvement > tolerance -> stop
    tolerance: float = 1e-4
    strategy: str = "numpy"  # "numpy" (operators above) | "deap" (DEAP's toolbox and loop)
    sbx_eta: float = 15.0  # deap: crowding degree of the simulated binary crossover
    polynomial_eta: float = 20.0  # deap: crowding degree of the polynomial mutation


class GAResult(NamedTuple):
    best: np.ndarray  # genes of the best individual ever evaluated
    fitness: float
    evaluations: int
    generations: int  # generations actually run (stagnation may stop early)
    logbook: tools.Logbook  # gen, nevals, best, mean, std per generation
    stopped_by: str  # "generations" | "stagnation"


def _wrap_or_reflect(genes: np.ndarray, circular: np.ndarray) -> np.ndarray:
    """Bring genes back into [0, 1]: reflect at the bounds, wrap circular ones."""
    wrapped = np.mod(genes, 1.0)
    reflected = np.abs(genes)
    reflected = np.where(reflected > 1.0, 2.0 - reflected, reflected)
    return np.where(circular, wrapped, np.clip(reflected, 0.0, 1.0))


def _tournament(fitness: np.ndarray, count: int, size: int, rng: np.random.Generator) -> np.ndarray:
    entrants = rng.integers(0, fitness.size, size=(count, size))
    return entrants[np.arange(count), np.argmin(fitness[entrants], axis=1)]


def _offspring(
    parents: np.ndarray,
    circular: np.ndarray,
    options: GAOptions,
    sigma: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """BLX-alpha crossover on pairs, then Gaussian mutation; all genes stay in [0, 1]."""
    children = parents.copy()
    m, d = children.shape
    for j in range(0, m - 1, 2):
        if rng.random() >= options.crossover:
            continue
        a, b = children[j].copy(), children[j + 1].copy()
        # circular genes recombine along the short arc between the parents
        delta = np.where(circular, (b - a + 0.5) % 1.0 - 0.5, b - a)
        lo = np.minimum(0.0, delta) - options.blend * np.abs(delta)
        span = np.abs(delta) * (1.0 + 2.0 * options.blend)
        children[j] = a + lo + span * rng.random(d)
        children[j + 1] = a + lo + span * rng.random(d)
    mutate = np.less(rng.random(m), options.mutation)
    per_gene = rng.random((m, d)) < max(1.0 / d, 0.3)
    steps = rng.normal(0.0, sigma, size=(m, d))
    children += np.where(mutate[:, None] & per_gene, steps, 0.0)
    return _wrap_or_reflect(children, circular)


def minimize(
    fitness_of: BatchFitness,
    dims: int,
    options: GAOptions | None = None,
    seed: int = 0,
    circular: Sequence[bool] | np.ndarray | None = None,
    initial: np.ndarray | None = None,
    on_generation: Callable[[int, float], None] | None = None,
) -> GAResult:
    """Minimise ``fitness_of`` over [0, 1]^dims with the strategy ``options.strategy``.

    The first population is a Latin hypercube (every gene's range covered
    evenly), optionally with ``initial`` rows (e.g. the healthy point) in front.
    ``on_generation(gen, best)`` is called after every generation.
    """
    options = options if options is not None else GAOptions()
    if options.strategy == "deap":
        return _deap_ga(fitness_of, dims, options, seed, initial, on_generation)
    if options.strategy != "numpy":
        raise ValueError(f"unknown GA strategy {options.strategy!r}")
    return _numpy_ga(fitness_of, dims, options, seed, circular, initial, on_generation)


def _first_population(
    rng: np.random.Generator, m: int, dims: int, initial: np.ndarray | None
) -> np.ndarray:
    """A Latin hypercube of ``m`` rows, ``initial`` rows in front."""
    population = (np.argsort(rng.random((m, dims)), axis=0) + rng.random((m, dims))) / m
    if initial is not None and len(initial):
        seeds = np.atleast_2d(np.asarray(initial, float))[:m]
        population[: len(seeds)] = seeds
    return population


def _drawing_from(rng: random.Random, func: Callable, **names) -> Callable:
    """DEAP's ``func`` drawing from ``rng``: the same code with its module's names, but
    ``random`` (and any of ``names``) bound to the run's own; the draws are the ones the
    global :mod:`random` seeded alike would give."""
    copy = types.FunctionType(
        func.__code__, {**func.__globals__, "random": rng, **names}, func.__name__
    )
    copy.__defaults__, copy.__kwdefaults__ = func.__defaults__, func.__kwdefaults__
    return copy


def _deap_ga(
    fitness_of: BatchFitness,
    dims: int,
    options: GAOptions,
    seed: int,
    initial: np.ndarray | None,
    on_generation: Callable[[int, float], None] | None,
) -> GAResult:
    """The ``deap`` strategy (module docstring): mu = lambda = the population, every
    generation to the end. The loop is ``algorithms.eaMuPlusLambda``'s (``varOr``, evaluate
    the new individuals, select mu of parents + offspring), written out to report each
    generation's progress."""
    m = options.population
    draws = random.Random(seed)
    toolbox = base.Toolbox()
    toolbox.register(
        "mate",
        _drawing_from(draws, tools.cxSimulatedBinaryBounded),
        eta=options.sbx_eta,
        low=0.0,
        up=1.0,
    )
    toolbox.register(
        "mutate",
        _drawing_from(draws, tools.mutPolynomialBounded),
        eta=options.polynomial_eta,
        low=0.0,
        up=1.0,
        indpb=1.0 / dims,
    )
    select = _drawing_from(
        draws, tools.selTournament, selRandom=_drawing_from(draws, tools.selRandom)
    )
    toolbox.register("select", select, tournsize=options.tournament)
    vary = _drawing_from(draws, algorithms.varOr)
    hall = tools.HallOfFame(1)
    stats = _statistics()
    logbook = tools.Logbook()
    logbook.header = ["gen", "nevals", "best", "mean", "std"]

    def evaluate(individuals) -> int:
        fresh = [ind for ind in individuals if not ind.fitness.valid]
        if fresh:
            for ind, value in zip(fresh, np.asarray(fitness_of(np.array(fresh, float)), float)):
                ind.fitness.values = (float(value),)
        return len(fresh)

    def record(gen: int, nevals: int, new, kept) -> None:
        hall.update(new)
        logbook.record(gen=gen, nevals=nevals, **stats.compile(kept))
        if on_generation is not None:
            on_generation(gen, float(hall[0].fitness.values[0]))

    rng = np.random.default_rng(np.random.SeedSequence(seed))
    population = [
        creator.FaultCandidate(row.tolist()) for row in _first_population(rng, m, dims, initial)
    ]
    evaluations = evaluate(population)
    record(0, evaluations, population, population)
    for gen in range(1, options.generations + 1):
        offspring = vary(population, toolbox, m, options.crossover, options.mutation)
        nevals = evaluate(offspring)
        evaluations += nevals
        population = toolbox.select(population + offspring, m)
        record(gen, nevals, offspring, population)
    return GAResult(
        np.asarray(hall[0], float),
        float(hall[0].fitness.values[0]),
        evaluations,
        options.generations,
        logbook,
        "generations",
    )


def _statistics() -> tools.Statistics:
    stats = tools.Statistics(lambda ind: ind.fitness.values[0])
    stats.register("best", np.min)
    stats.register("mean", np.mean)
    stats.register("std", np.std)
    return stats


def _numpy_ga(
    fitness_of: BatchFitness,
    dims: int,
    options: GAOptions,
    seed: int,
    circular: Sequence[bool] | np.ndarray | None,
    initial: np.ndarray | None,
    on_generation: Callable[[int, float], None] | None,
) -> GAResult:
    """The ``numpy`` strategy: a generational GA (module docstring).

    Elitism keeps the ``elite`` best; a DEAP hall of fame keeps the best ever.
    Stops after ``options.generations`` or when the best fitness has not improved
    by ``tolerance`` (relative) for ``patience`` generations.
    """
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    circ = np.zeros(dims, bool) if circular is None else np.asarray(circular, bool)
    m = options.population
    population = _first_population(rng, m, dims, initial)
    fitness = np.asarray(fitness_of(population), float)
    evaluations = m

    hall = tools.HallOfFame(1)
    stats = _statistics()
    logbook = tools.Logbook()
    logbook.header = ["gen", "nevals", "best", "mean", "std"]

    def record(gen: int, nevals: int) -> None:
        individuals = []
        for genes, value in zip(population, fitness):
            ind = creator.FaultCandidate(genes.tolist())
            ind.fitness.values = (float(value),)
            individuals.append(ind)
        hall.update(individuals)
        logbook.record(gen=gen, nevals=nevals, **stats.compile(individuals))
        if on_generation is not None:
            on_generation(gen, float(hall[0].fitness.values[0]))

    record(0, m)
    best_so_far = float(hall[0].fitness.values[0])
    stale = 0
    stopped_by = "generations"
    generations = options.generations
    for gen in range(1, options.generations + 1):
        sigma = options.sigma_start * (options.sigma_end / options.sigma_start) ** (
            (gen - 1) / max(options.generations - 1, 1)
        )
        order = np.argsort(fitness, kind="stable")
        elite = population[order[: options.elite]]
        chosen = _tournament(fitness, m - options.elite, options.tournament, rng)
        children = _offspring(population[chosen], circ, options, sigma, rng)
        child_fitness = np.asarray(fitness_of(children), float)
        evaluations += children.shape[0]
        population = np.vstack([elite, children])
        fitness = np.concatenate([fitness[order[: options.elite]], child_fitness])
        record(gen, children.shape[0])
        current = float(hall[0].fitness.values[0])
        if current < best_so_far * (1.0 - options.tolerance):
            best_so_far, stale = current, 0
        else:
            stale += 1
        if stale >= options.patience:
            stopped_by, generations = "stagnation", gen
            break
    best = np.asarray(hall[0], float)
    return GAResult(
        best, float(hall[0].fitness.values[0]), evaluations, generations, logbook, stopped_by
    )
