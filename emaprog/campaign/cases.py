"""Monte-Carlo fault campaigns (docs/reference.md, Campaign YAML and Campaign results): sampling, execution, and the resumable case dataset.

A campaign is ``cases`` independent twin experiments on one base scenario:
draw true faults from the campaign's distributions, simulate the noisy
Reference Model, identify the faults with the GA over the Monitor Model, and
store truth, estimate and error as one row.

Reproducibility: case ``k`` draws everything (its faults, the Reference noise
seed and the GA seed) from ``SeedSequence(seed, spawn_key=(k,))`` -- the same
stream ``SeedSequence(seed).spawn(...)`` hands its k-th child -- so a case's
numbers depend on the master seed and its index only, never on the worker that
ran it, the number of workers or the order of completion.

Storage (``RESULTS_DIR``):

* ``manifest.json`` -- the campaign, its base scenario and parameter values,
  and their hash; ``--resume`` refuses a campaign whose hash changed;
* ``cases/case-NNNNNN.parquet`` -- one file per finished case, written under a
  temporary dot-name and renamed, so a crash never leaves half a case and
  Parquet readers never see the temporary;
* ``failures/case-NNNNNN.json`` -- a case that raised: its error and
  traceback; the campaign goes on, and ``--resume`` tries it again.
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import threading
import time
import traceback
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ..config import parameters as parameter_sets
from ..config.parameters import Parameters
from ..config.scenario import SPREAD_PARAMETERS, Campaign, Faults, IdentifySettings, Scenario
from ..errors import InputError
from ..faults import (
    CATALOGUE,
    FAULT_NAMES,
    PHASE_FAULT,
    PHASES,
    QUANTITIES,
    Fault,
    flatten,
    worst_phase,
)
from ..identification import identify_trace
from ..identification import result as verdicts
from ..identification.defaults import resolve as resolve_settings
from ..identification.objective import NUISANCE_DEFAULTS, ResidualRecording, recording_residual
from ..io.storage import write_json
from ..models import reference
from ..models.common import inputs

SEED_LIMIT = 2**32  # scenario and GA seeds are uint32
CASE_FILE = "case-{:06d}"


# ---------------------------------------------------------------- sampling
class Commissioning(NamedTuple):
    """A case's healthy commissioning recording: its noise seed and hinge moment."""

    seed: int
    hinge_moment: float  # [N m]


class CaseSpec(NamedTuple):
    """Everything a worker needs to run one case; picklable, no open files."""

    case_id: int
    healthy: bool  # sampled as an all-healthy case (false-alarm check)
    scenario: Scenario  # base scenario with this case's faults and noise seed
    params: Parameters  # the set identification starts from (the shipped one)
    settings: IdentifySettings  # with this case's GA seed
    campaign_hash: str
    unit: Parameters | None = None  # the case's own unit (actuator_spread), None: params
    hinge_moment: float = 0.0  # [N m] unknown to the identification
    commission: Commissioning | None = None  # commission the unit first (campaign commission)


def identify_settings(campaign: Campaign, base: Scenario) -> IdentifySettings:
    """The campaign's ``identify:`` block when it has one, else the base scenario's."""
    return campaign.identify if "identify" in campaign.model_fields_set else base.identify


def _draw(layout: str, rng: np.random.Generator) -> tuple:
    """The uniform draws of one fault, by layout (every draw made, used or not)."""
    if layout == "scalar":
        return (rng.random(),)
    if layout == "per_phase":
        return int(rng.integers(3)), rng.random()  # phase, fraction
    return rng.random(), rng.random()  # polar: magnitude, angle


def _scaled(dist, u: float, healthy_value: float) -> float:
    if dist is None:
        return healthy_value
    lo, hi = dist.uniform
    return float(lo + u * (hi - lo))


def _fault_value(fault: Fault, dist, draws: tuple):
    """A fault's YAML value from its distribution (``None``: healthy) and its draws."""
    if fault.layout == "scalar":
        return _scaled(dist, draws[0], fault.quantities[0].healthy)
    value = {q.key: q.healthy for q in fault.quantities}
    if dist is None:
        return value
    if fault.layout == "per_phase":
        phase = PHASES[draws[0]] if dist.phase == "any" else dist.phase
        value[phase] = _scaled(dist.fraction, draws[1], 0.0)
        return value
    magnitude, angle = fault.quantities
    return {
        magnitude.key: _scaled(dist.zeta, draws[0], magnitude.healthy),
        angle.key: _scaled(dist.phase, draws[1], angle.healthy),
    }


def sample_case(campaign: Campaign, case_id: int) -> tuple[bool, Faults, int, int]:
    """Draw case ``case_id``'s faults, Reference noise seed and GA seed.

    Every draw is made whether or not its distribution is given, in a fixed
    order (catalogue order), so adding a distribution to a campaign does not
    reshuffle the others' streams. Returns (healthy, faults, noise_seed, ga_seed).
    """
    rng = np.random.default_rng(np.random.SeedSequence(campaign.seed, spawn_key=(case_id,)))
    d = campaign.faults
    healthy = bool(rng.random() < d.healthy_fraction)  # type: ignore[attr-defined]  # built at import
    draws = {f.name: _draw(f.layout, rng) for f in CATALOGUE}
    noise_seed, ga_seed = (int(s) for s in rng.integers(0, SEED_LIMIT, size=2))
    if healthy:
        return True, Faults(), noise_seed, ga_seed
    faults = Faults.model_validate(
        {f.name: _fault_value(f, getattr(d, f.name), draws[f.name]) for f in CATALOGUE}
    )
    return False, faults, noise_seed, ga_seed


def sample_unit(campaign: Campaign, case_id: int) -> tuple[dict[str, float], float, Commissioning]:
    """Case ``case_id``'s unit factors, hinge moment and commissioning recording.

    Drawn from the same stream as :func:`sample_case`, after all of its draws, every
    draw made whether or not its distribution is given: a campaign without spread keeps
    exactly the cases it had before these keys existed.
    """
    rng = np.random.default_rng(np.random.SeedSequence(campaign.seed, spawn_key=(case_id,)))
    rng.random()
    for fault in CATALOGUE:
        _draw(fault.layout, rng)
    rng.integers(0, SEED_LIMIT, size=2)
    spread = {name: rng.random() for name in SPREAD_PARAMETERS}
    hinge_u, commission_hinge_u = rng.random(), rng.random()
    commission_seed = int(rng.integers(0, SEED_LIMIT))
    factors = {
        name: 1.0 + _scaled(getattr(campaign.actuator_spread, name), u, 0.0)
        for name, u in spread.items()
    }
    hinge = _scaled(campaign.hinge_moment, hinge_u, 0.0)
    return (
        factors,
        hinge,
        Commissioning(commission_seed, _scaled(campaign.hinge_moment, commission_hinge_u, 0.0)),
    )


def case_specs(
    campaign: Campaign,
    base: Scenario,
    params: Parameters,
    campaign_hash: str,
    case_ids: Iterable[int],
) -> Iterator[CaseSpec]:
    """The specs of the given cases (lazily: a large campaign is never all in memory)."""
    settings = identify_settings(campaign, base)
    for case_id in case_ids:
        healthy, faults, noise_seed, ga_seed = sample_case(campaign, case_id)
        spec = make_spec(
            case_id,
            healthy,
            f"{campaign.name}-case-{case_id}",
            base,
            faults,
            noise_seed,
            ga_seed,
            settings,
            params,
            campaign_hash,
        )
        factors, hinge, commissioning = sample_unit(campaign, case_id)
        spread = {k: f for k, f in factors.items() if f != 1.0}
        unit = (
            parameter_sets.scaled(params, spread, f"{campaign.name}-case-{case_id} unit")
            if spread
            else None
        )
        yield spec._replace(
            unit=unit, hinge_moment=hinge, commission=commissioning if campaign.commission else None
        )


def make_spec(
    case_id: int,
    healthy: bool,
    name: str,
    base: Scenario,
    faults: Faults,
    noise_seed: int,
    ga_seed: int,
    settings: IdentifySettings,
    params: Parameters,
    digest: str,
) -> CaseSpec:
    """One case: the base scenario with these faults and noise seed, the GA with its seed."""
    scenario = Scenario.model_validate(
        {
            **base.model_dump(mode="json"),
            "name": name,
            "seed": noise_seed,
            "faults": faults.model_dump(mode="json"),
            "identify": settings.model_dump(mode="json"),
        }
    )
    case_settings = IdentifySettings.model_validate(
        {
            **settings.model_dump(mode="json"),
            "ga": {**settings.ga.model_dump(mode="json"), "seed": ga_seed},
        }
    )
    return CaseSpec(case_id, healthy, scenario, params, case_settings, digest)


# ---------------------------------------------------------------- one case
def with_hinge(scenario: Scenario, hinge_moment: float) -> Scenario:
    """The scenario with a constant hinge moment [N m] added to its load."""
    if hinge_moment == 0.0:
        return scenario
    load = scenario.load.model_dump(mode="json")
    if load["kind"] == "none":
        load = {"kind": "constant", "torque": 0.0}
    load["torque"] = load["torque"] + hinge_moment
    return Scenario.model_validate({**scenario.model_dump(mode="json"), "load": load})


def commission_case(spec: CaseSpec, unit: Parameters) -> tuple[Parameters, dict, ResidualRecording]:
    """Commission the case's unit from its own healthy recording.

    Returns the commissioned set, the row's commissioning columns and the recording's
    residual against the commissioned healthy Monitor (``identify.nominal_correction:
    recording``).
    """
    from ..fitting import commission as commissioning

    assert spec.commission is not None  # the case commissions its unit
    healthy = Scenario.model_validate(
        {
            **spec.scenario.model_dump(mode="json"),
            "faults": Faults().model_dump(mode="json"),
            "seed": spec.commission.seed,
        }
    )
    recording = reference.simulate(with_hinge(healthy, spec.commission.hinge_moment), unit)
    prepared = commissioning.prepare(recording, f"case {spec.case_id} commissioning", spec.params)
    fit = commissioning.fit([prepared], spec.params)
    commissioning.check_explained(fit, [prepared])
    commissioned = parameter_sets.scaled(
        spec.params,
        {k: fit.values[k] / fit.base[k] for k in fit.values},
        f"case {spec.case_id} commissioned unit",
    )
    true = {**unit.spec.electrical.model_dump(), **unit.spec.mechanical.model_dump()}
    row: dict[str, float | str] = {
        f"commission_err_{k}": float(v / true[k] - 1.0) for k, v in fit.values.items()
    }
    row["commission_err_hinge_moment"] = float(fit.hinge_moments[0] - spec.commission.hinge_moment)
    row["commission_undetermined"] = ",".join(fit.not_determined)
    # the fit's own (linearised) relative standard errors, NaN where held: what the
    # commissioning model-error floors are calibrated from (benchmarks/commission_errors.py)
    row.update(
        {
            f"commission_se_{k}": float(fit.standard_errors[k] / v)
            if k in fit.standard_errors
            else float("nan")
            for k, v in fit.values.items()
        }
    )
    row["commission_se_hinge_moment"] = float(fit.hinge_errors[0])
    residual = recording_residual(
        recording,
        prepared.inputs,
        commissioned,
        fit.hinge_moments[0],
        f"case {spec.case_id} commissioning",
    )
    return commissioned, row, residual


def run_case(spec: CaseSpec) -> dict:
    """Simulate and identify one case; the case row (docs/reference.md, Campaign results) (plain Python values).

    The trace is the case's unit (``spec.unit``) under its hinge moment; the
    identification knows neither: it starts from ``spec.params`` (or the unit it
    commissions first) and the base scenario's load.
    """
    start = time.perf_counter()
    unit = spec.unit if spec.unit is not None else spec.params
    trace = reference.simulate(with_hinge(spec.scenario, spec.hinge_moment), unit)
    simulated = time.perf_counter()
    params, recordings = spec.params, []
    commission_row: dict[str, float | str] = {}
    if spec.commission is not None:
        params, commission_row, residual = commission_case(spec, unit)
        recordings = [residual]
    commissioned = time.perf_counter()
    inp = inputs(spec.scenario, params)
    settings = resolve_settings(
        spec.settings,
        trace.metadata,
        params,
        real_unit=spec.unit is not None or spec.commission is not None,
    ).settings
    result = identify_trace(
        trace,
        inp,
        params,
        settings,
        show_progress=False,
        recordings=recordings,
        commissioned=spec.commission is not None,
    )
    truth = flatten(spec.scenario.faults)
    error = verdicts.errors(result.estimate, truth)
    confidence = result.confidence
    health = verdicts.health(
        result.estimate, spec.settings.estimate, spec.params, confidence.inconclusive
    )
    true_health = verdicts.health(truth, list(FAULT_NAMES), spec.params)
    row: dict = {
        "case_id": spec.case_id,
        "healthy_case": spec.healthy,
        "noise_seed": spec.scenario.seed,
        "ga_seed": spec.settings.ga.seed,
    }
    nan = float("nan")
    for name in QUANTITIES:
        row[f"true_{name}"] = float(truth[name])
        row[f"est_{name}"] = float(result.estimate[name])
        err = error[name]
        row[f"err_{name}"] = nan if err is None else float(err)
        low, high = confidence.interval.get(name, (nan, nan))
        row[f"low_{name}"], row[f"high_{name}"] = float(low), float(high)
        row[f"se_{name}"] = float(confidence.standard_error.get(name, nan))
        row[f"sigma_{name}"] = float(confidence.linear_error.get(name, nan))
    for fault in FAULT_NAMES:
        row[f"health_{fault}"] = health.get(fault, "not estimated")
        row[f"true_health_{fault}"] = true_health[fault]
    row.update(
        {
            f"true_{PHASE_FAULT}_phase": worst_phase(truth) or "none",
            f"est_{PHASE_FAULT}_phase": _detected_phase(
                result.estimate, health, confidence.isolation
            ),
            "fitness": float(result.fitness),
            "correction": result.objective.correction.applied,
            "floor_ratio": float(confidence.floor.ratio),
            "fault_load": float(confidence.fault_load),
            "twin": bool(confidence.twin),
            "basis": confidence.basis,
            "echo": bool(confidence.echo),
            **{
                f"echo_{q}": float((confidence.echo or {}).get("errors", {}).get(q, nan))
                for q in QUANTITIES
            },
            "isolation_confidence": float(confidence.isolation["confidence"])
            if confidence.isolation
            else nan,
            "evaluations": int(result.evaluations),
            "generations": int(result.generations),
            "simulate_s": simulated - start,
            "identify_s": result.elapsed_s,
            "true_hinge_moment": float(spec.hinge_moment),
            **{
                f"est_{name}": float(result.estimate[name])
                if name in (settings.nuisances or [])
                else float("nan")
                for name in NUISANCE_DEFAULTS
            },
            **{
                f"{column}_{name}": float(errors.get(name, float("nan")))
                for name in NUISANCE_DEFAULTS
                for column, errors in (
                    ("se", confidence.standard_error),
                    ("sigma", confidence.linear_error),
                )
            },
            # the winding resistance the identification should find, over the set it uses
            "true_resistance_factor": float(
                unit.spec.electrical.phase_resistance / params.spec.electrical.phase_resistance
            ),
        }
    )
    if spec.commission is not None:
        row.update(commission_row, commission_s=commissioned - simulated)
    return row


def _detected_phase(
    estimate: dict[str, float], health: dict[str, str], isolation: dict | None = None
) -> str:
    """The phase named faulty (:func:`~emaprog.identification.confidence.named_phase`)."""
    from ..identification.confidence import named_phase

    flagged = health.get(PHASE_FAULT, "nominal") in ("incipient", "degraded")
    return named_phase(estimate, flagged, isolation) or "none"


class Failure(NamedTuple):
    case_id: int
    error: str
    traceback: str


def run_case_safely(spec: CaseSpec) -> dict | Failure:
    """:func:`run_case`, with any exception turned into a :class:`Failure` record."""
    try:
        return run_case(spec)
    except Exception as exc:  # noqa: BLE001 - a failed case must not stop the campaign
        return Failure(spec.case_id, f"{type(exc).__name__}: {exc}", traceback.format_exc())


# ---------------------------------------------------------------- storage
TIMING_COLUMNS = ("simulate_s", "identify_s")


def campaign_hash(campaign: Campaign, base: Scenario, params: Parameters) -> str:
    """Hash of what decides the cases' numbers: campaign, base scenario, parameter values."""
    content = {
        "campaign": campaign.model_dump(mode="json", exclude={"scenario"}),
        "identify": identify_settings(campaign, base).model_dump(mode="json"),
        "scenario": base.model_dump(mode="json"),
        "parameters": params.values(),
    }
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()


class CaseStore:
    """The results folder of one campaign: manifest, one Parquet file per case, failures."""

    def __init__(self, folder: str | Path):
        self.folder = Path(folder)
        self.cases = self.folder / "cases"
        self.failures = self.folder / "failures"
        self.manifest = self.folder / "manifest.json"

    def finished(self) -> set[int]:
        """Ids of the cases whose file is complete (temporaries are dot-names, never listed)."""
        if not self.cases.is_dir():
            return set()
        return {int(p.stem.split("-")[1]) for p in self.cases.glob("case-*.parquet")}

    def failed(self) -> dict[int, str]:
        if not self.failures.is_dir():
            return {}
        out = {}
        for path in sorted(self.failures.glob("case-*.json")):
            out[int(path.stem.split("-")[1])] = json.loads(path.read_text())["error"]
        return out

    def open(self, source: Path, digest: str, manifest: dict, resume: bool) -> None:
        """Start or continue the campaign in this folder; refuses to mix campaigns.

        ``digest`` hashes what decides the cases' numbers; it is stored in the
        manifest as ``content_hash`` and must match on ``resume``.
        """
        if self.manifest.is_file():
            try:
                stored = json.loads(self.manifest.read_text())["content_hash"]
            except (json.JSONDecodeError, KeyError, UnicodeDecodeError):
                raise InputError(
                    self.manifest,
                    "is not a readable campaign manifest; choose another results folder",
                ) from None
            if not resume:
                raise InputError(
                    self.folder,
                    "already holds a campaign's results; pass --resume to "
                    "continue it, or choose another results folder (-o)",
                )
            if stored != digest:
                raise InputError(
                    source,
                    "changed since the first run in "
                    f"{self.folder} (campaign, base scenario or parameter values "
                    "differ); --resume only continues the same campaign: use another "
                    "results folder (-o)",
                )
        elif self.finished():
            raise InputError(
                self.folder,
                "holds case files but no manifest.json; choose another results folder (-o)",
            )
        self.cases.mkdir(parents=True, exist_ok=True)
        for stale in self.cases.glob(".case-*"):  # temporaries of a killed run
            stale.unlink()
        if not self.manifest.is_file():
            write_json(self.manifest, {**manifest, "content_hash": digest})

    def write_case(self, row: dict, provenance: dict) -> Path:
        """One case as its own Parquet file, atomically, with provenance in the file metadata."""
        table = pa.Table.from_pylist([row])
        table = table.replace_schema_metadata({b"emaprog": json.dumps(provenance).encode()})
        name = CASE_FILE.format(row["case_id"])
        tmp = self.cases / f".{name}.{os.getpid()}.tmp"
        try:
            pq.write_table(table, tmp)
            os.replace(tmp, self.cases / f"{name}.parquet")
        except BaseException:  # Ctrl-C or a full disk mid-write: leave no temporary behind
            tmp.unlink(missing_ok=True)
            raise
        stale_failure = self.failures / f"{name}.json"
        if stale_failure.exists():
            stale_failure.unlink()
        return self.cases / f"{name}.parquet"

    def write_failure(self, failure: Failure) -> Path:
        self.failures.mkdir(parents=True, exist_ok=True)
        return write_json(
            self.failures / f"{CASE_FILE.format(failure.case_id)}.json", failure._asdict()
        )

    def read(self) -> pd.DataFrame:
        """All finished cases, sorted by case id."""
        files = sorted(self.cases.glob("case-*.parquet"))
        if not files:
            return pd.DataFrame()
        frame = pd.concat([pq.read_table(f).to_pandas() for f in files], ignore_index=True)
        return frame.sort_values("case_id", kind="stable").reset_index(drop=True)


# ---------------------------------------------------------------- execution
OnResult = Callable[[dict | Failure], None]


def _worker_init(numba_threads: int) -> None:
    """Local pool worker: leave Ctrl-C to the parent, share the cores without oversubscribing."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    import numba

    numba.set_num_threads(max(1, min(numba_threads, numba.config.NUMBA_NUM_THREADS)))  # type: ignore[attr-defined]


def run_serial(specs: Iterable[CaseSpec], on_result: OnResult) -> None:
    """One worker: run the cases in this process (no pool to start)."""
    for spec in specs:
        on_result(run_case_safely(spec))


def run_local(specs: Iterable[CaseSpec], workers: int, on_result: OnResult) -> None:
    """A local process pool of ``workers`` spawned processes.

    Each worker gets ``cores // workers`` numba threads (the GA's batched
    evaluation is a parallel kernel), so workers x threads never exceeds the
    cores. On Ctrl-C the pending cases are cancelled and the running ones are
    stopped; every case finished before that is already on disk.
    """
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    threads = max(1, (os.cpu_count() or 1) // workers)
    pool = ProcessPoolExecutor(
        workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_worker_init,
        initargs=(threads,),
    )
    pending: set = set()
    queue = iter(specs)
    try:
        # keep a bounded number of cases in flight: a million-case campaign is fed lazily
        for spec in queue:
            pending.add(pool.submit(run_case_safely, spec))
            if len(pending) >= 2 * workers:
                break
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                on_result(future.result())
                following = next(queue, None)
                if following is not None:
                    pending.add(pool.submit(run_case_safely, following))
    except BaseException:
        for future in pending:
            future.cancel()
        # the executor has no public "stop running work": end the worker processes directly
        for process in list(getattr(pool, "_processes", {}).values()):
            process.terminate()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


_DASK_TASK_LOCK = threading.Lock()


def run_case_on_dask(spec: CaseSpec) -> dict | Failure:
    """A Dask task: one case at a time per worker process.

    numba's default threading layer must not run parallel kernels from two
    threads of one process at once, so a worker started with several threads
    runs its cases one after another; start Dask workers with ``--nthreads 1``
    and one process per core (``dask worker ADDRESS --nworkers N --nthreads 1``).
    """
    import numba

    with _DASK_TASK_LOCK:
        numba.set_num_threads(1)
        return run_case_safely(spec)


def connect(address: str):
    """A Dask client of the scheduler at ``address``; InputError when it cannot be reached."""
    try:
        from distributed import Client
    except ImportError:
        raise InputError(
            "--scheduler", "needs the dask[distributed] package (pip install 'dask[distributed]')"
        ) from None
    try:
        return Client(address, timeout="5s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError(
            "--scheduler",
            f"cannot reach a Dask scheduler at '{address}' "
            f"({type(exc).__name__}: {exc}); give tcp://HOST:PORT of a running "
            "scheduler",
        ) from None


def run_dask(specs: Iterable[CaseSpec], client, on_result: OnResult) -> None:
    """The same cases as tasks of a Dask cluster (``client`` from :func:`connect`)."""
    from distributed import as_completed

    futures = [
        client.submit(
            run_case_on_dask,
            spec,
            pure=False,
            key=f"emaprog-{spec.campaign_hash[:12]}-{spec.case_id}",
        )
        for spec in specs
    ]
    try:
        for future in as_completed(futures, loop=client.loop):
            on_result(future.result())
    except BaseException:
        client.cancel(futures)
        raise


class Interrupted(KeyboardInterrupt):
    """Ctrl-C during a run of cases; the message says what is on disk and how to go on."""


def worker_count(requested: int | None, cases: int) -> int:
    """Local workers for ``cases`` cases: as asked (default all cores), never more than cases."""
    return max(1, min(requested or os.cpu_count() or 1, cases or 1))


def execute(
    specs: Iterable[CaseSpec],
    store: CaseStore,
    provenance: dict,
    count: int,
    workers: int,
    client,
    label: str,
    already: int,
    show_progress: bool = True,
) -> dict[str, int]:
    """Run ``count`` cases on the chosen back-end, storing each as it finishes.

    ``client`` (a Dask client) wins over ``workers``; one worker runs the cases
    in this process. Returns ``{"done": n, "failed": n}``; Ctrl-C raises
    :class:`Interrupted` once the workers are stopped.
    """
    from .. import progress

    counts = {"done": 0, "failed": 0}
    with progress.task(label, count, show_progress) as advance:

        def on_result(result: dict | Failure) -> None:
            if isinstance(result, Failure):
                store.write_failure(result)
                counts["failed"] += 1
            else:
                store.write_case(result, {**provenance, "case_id": result["case_id"]})
                counts["done"] += 1
            advance(1, done=already + counts["done"], failed=counts["failed"])

        try:
            if client is not None and count:
                run_dask(specs, client, on_result)
            elif workers == 1 or not count:
                run_serial(specs, on_result)
            else:
                run_local(specs, workers, on_result)
        except KeyboardInterrupt:
            raise Interrupted(
                f"{already + counts['done']} cases are stored in {store.cases}; "
                "run the same command with --resume to finish"
            ) from None
    return counts


def load_parameters(campaign_path: Path, campaign, base: Scenario) -> Parameters:
    """The base scenario's parameter set, resolved next to the file that names it.

    ``campaign`` is a Campaign or a History: anything with a ``scenario`` that is
    a path (relative to ``campaign_path``) or an inline Scenario.
    """
    if isinstance(campaign.scenario, str):
        folder = (campaign_path.parent / campaign.scenario).parent
    else:
        folder = campaign_path.parent
    return parameter_sets.load(base.parameters, relative_to=folder, source=campaign_path)
