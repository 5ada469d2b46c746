"""The default GA against the optimisers a user would pick instead, on the same objective.

On the 10 cases of ``campaigns/regression.yaml`` (random fault combinations on noisy
Reference traces, each case's own noise and optimiser seed) every optimiser
searches the same genes, bounds and batched Monitor evaluator
(:class:`emaprog.identification.objective.Objective`, nominal correction
applied), with the same global budget (the default GA's Monitor runs on that case),
and hands its best to the same local polish
(:func:`emaprog.identification.run.polish`, the default least-squares one):

* ``ga`` -- emaprog's GA (DEAP individuals, hall of fame and logbook; its own
  numpy operators: tournament, BLX-alpha crossover, decaying Gaussian mutation);
* ``deap-toolbox`` -- emaprog's GA with ``strategy: deap``: DEAP's own operators
  and (mu + lambda) loop (``selTournament``, ``cxSimulatedBinaryBounded``,
  ``mutPolynomialBounded``, ``varOr``), seeded through :mod:`random` per
  identification, each generation evaluated in one batch;
* ``de`` -- :func:`scipy.optimize.differential_evolution`, vectorised, Latin
  hypercube start, no built-in polish;
* ``cma-es`` -- DEAP's ``cma.Strategy`` (lambda: the GA's population), out-of-box genes
  evaluated clipped with a quadratic penalty;
* ``multistart`` -- bounded Powell from 6 Latin-hypercube starts sharing the budget.

Table: share of cases within tolerance per fault (short circuit: worst phase), p95
errors, median Monitor runs and wall time per case (2 cores: the evaluator's
parallel loop). Run: ``python benchmarks/optimizers.py [--json] [--cases N]``; the
last line with ``--json`` is one JSON list.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
from _output import finish, parser  # the sibling module benchmarks/_output.py
from deap import cma, creator
from scipy.optimize import differential_evolution
from scipy.optimize import minimize as local_minimize

from emaprog.campaign.cases import case_specs, load_parameters, with_hinge
from emaprog.config.scenario import load_campaign
from emaprog.faults import FAULTS, QUANTITIES, flatten
from emaprog.identification import result as verdicts
from emaprog.identification.ga import GAOptions
from emaprog.identification.ga import minimize as ga_minimize
from emaprog.identification.objective import Objective, reference_correction
from emaprog.identification.run import DEFAULT_GA, ga_budget, polish
from emaprog.models import reference
from emaprog.models.common import inputs

ROOT = Path(__file__).resolve().parent.parent
CAMPAIGN = ROOT / "campaigns" / "regression.yaml"
POPULATION = DEFAULT_GA[0]  # DE and CMA-ES generations of the GA's size
STARTS = 6


def _deap_toolbox(objective: Objective, budget: int, seed: int) -> np.ndarray:
    """emaprog's ``deap`` GA strategy with as many generations as the budget pays for."""
    options = GAOptions(
        population=POPULATION, generations=max(1, budget // POPULATION - 1), strategy="deap"
    )
    return ga_minimize(
        objective, objective.dims, options, seed=seed, initial=objective.healthy_genes()[None]
    ).best


def _de(objective: Objective, budget: int, seed: int) -> np.ndarray:
    dims = objective.dims
    popsize = max(1, math.ceil(POPULATION / dims))
    iterations = max(1, budget // (popsize * dims) - 1)
    result = differential_evolution(
        lambda x: objective(np.ascontiguousarray(x.T)),
        [(0.0, 1.0)] * dims,
        popsize=popsize,
        maxiter=iterations,
        tol=0.0,
        seed=seed,
        polish=False,
        vectorized=True,
        updating="deferred",
        init="latinhypercube",
    )
    return result.x


def _cma(objective: Objective, budget: int, seed: int) -> np.ndarray:
    np.random.seed(seed % 2**32)  # DEAP's cma draws from numpy's global generator
    strategy = cma.Strategy(centroid=[0.5] * objective.dims, sigma=0.25, lambda_=POPULATION)
    best, best_fitness, spent = None, math.inf, 0
    while spent + POPULATION <= budget:
        population = strategy.generate(creator.FaultCandidate)
        raw = np.array(population, float)
        inside = np.where(objective.circular, np.mod(raw, 1.0), np.clip(raw, 0.0, 1.0))
        fitness = objective(inside)
        spent += POPULATION
        penalised = fitness * (1.0 + np.sum((raw - inside) ** 2 * ~objective.circular, axis=1))
        for ind, value in zip(population, penalised):
            ind.fitness.values = (float(value),)
        strategy.update(population)
        k = int(np.argmin(fitness))
        if fitness[k] < best_fitness:
            best, best_fitness = inside[k], float(fitness[k])
    return best


def _multistart(objective: Objective, budget: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    dims = objective.dims
    starts = (np.argsort(rng.random((STARTS, dims)), axis=0) + rng.random((STARTS, dims))) / STARTS
    best, best_fitness = None, math.inf
    for start in starts:
        found = local_minimize(
            lambda x: float(objective(x[None])[0]),
            start,
            method="Powell",
            bounds=[(0.0, 1.0)] * dims,
            options={"maxfev": budget // STARTS, "xtol": 1e-4, "ftol": 1e-8},
        )
        if found.fun < best_fitness:
            best, best_fitness = found.x, float(found.fun)
    return best


#: The alternatives, each called with the GA's Monitor runs on the case as its budget.
OPTIMISERS = {"deap-toolbox": _deap_toolbox, "de": _de, "cma-es": _cma, "multistart": _multistart}


def run_cases(count: int) -> list[dict]:
    campaign, base_scenario = load_campaign(CAMPAIGN)
    params = load_parameters(CAMPAIGN, campaign, base_scenario)
    rows = []
    for spec in case_specs(campaign, base_scenario, params, "optimizers", range(count)):
        trace = reference.simulate(with_hinge(spec.scenario, spec.hinge_moment), params)
        inp = inputs(spec.scenario, params)
        correction = reference_correction(inp, params)
        truth = flatten(spec.scenario.faults)
        budget = 0
        for name in ("ga", *OPTIMISERS):
            objective = Objective(trace, inp, params, spec.settings, correction=correction)
            start = time.perf_counter()
            if name == "ga":  # first: its Monitor runs are every optimiser's budget
                population, generations = ga_budget(
                    spec.settings.ga, trace.sample_rate, params.hysteresis_form
                )
                options = GAOptions(population=population, generations=generations)
                found = ga_minimize(
                    objective,
                    objective.dims,
                    options,
                    seed=spec.settings.ga.seed,
                    circular=objective.circular,
                    initial=objective.healthy_genes()[None],
                ).best
                budget = objective.evaluations
            else:
                found = OPTIMISERS[name](objective, budget, spec.settings.ga.seed)
            global_runs = objective.evaluations
            genes, fitness, _ = polish(
                objective, found, float(objective(found[None])[0]), spec.settings.polish
            )
            estimate = objective.values(genes)
            errors = verdicts.errors(estimate, truth)
            rows.append(
                {
                    "optimiser": name,
                    "case": spec.case_id,
                    "fitness": fitness,
                    "global_runs": global_runs,
                    "runs": objective.evaluations,
                    "wall_s": time.perf_counter() - start,
                    **{f"err_{q}": errors[q] for q in QUANTITIES},
                    **{f"true_{q}": truth[q] for q in QUANTITIES},
                }
            )
            print(
                f"case {spec.case_id} {name:13s} fitness {fitness:.3e} runs "
                f"{objective.evaluations} {rows[-1]['wall_s']:.1f} s",
                file=sys.stderr,
                flush=True,
            )
    return rows


def summarise(rows: list[dict]) -> list[dict]:
    out = []
    for name in ("ga", *OPTIMISERS):
        mine = [r for r in rows if r["optimiser"] == name]
        entry = {"optimiser": name, "cases": len(mine)}
        for fault in FAULTS.values():
            bad = []
            worst = []
            for r in mine:
                errs = []
                for q in fault.magnitudes:
                    e = abs(r[f"err_{q.name}"])
                    if q.measure == "relative":
                        e /= r[f"true_{q.name}"]
                    errs.append(e / q.tolerance)
                worst.append(max(errs))
                bad.append(max(errs) > 1.0)
            entry[f"{fault.name}_within"] = 1.0 - float(np.mean(bad))
            entry[f"{fault.name}_p95_over_tolerance"] = float(np.percentile(worst, 95))
        entry["median_runs"] = float(np.median([r["runs"] for r in mine]))
        entry["median_wall_s"] = float(np.median([r["wall_s"] for r in mine]))
        entry["median_fitness"] = float(np.median([r["fitness"] for r in mine]))
        out.append(entry)
    return out


def table(summary: list[dict]) -> str:
    faults = list(FAULTS)
    head = (
        "| optimiser | "
        + " | ".join(f"{f} within" for f in faults)
        + " | "
        + " | ".join(f"{f} p95/tol" for f in faults)
        + " | Monitor runs | wall [s] |"
    )
    lines = [head, "|" + "---|" * (2 * len(faults) + 3)]
    for s in summary:
        lines.append(
            f"| {s['optimiser']} | "
            + " | ".join(f"{s[f'{f}_within']:.0%}" for f in faults)
            + " | "
            + " | ".join(f"{s[f'{f}_p95_over_tolerance']:.2f}" for f in faults)
            + f" | {s['median_runs']:.0f} | {s['median_wall_s']:.1f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    arguments = parser(__doc__)
    arguments.add_argument("--cases", type=int, default=10, help="regression cases to run")
    args = arguments.parse_args(argv)
    return finish(summarise(run_cases(args.cases)), table, args.json)


if __name__ == "__main__":
    sys.exit(main())
