"""Running a campaign (docs/reference.md, Campaign YAML and Campaign results): open or resume
its store, run the cases still to do, summarise every finished case, compare with a
baseline, write the summary and its figures."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import NamedTuple

import pandas as pd

from .. import __version__
from ..config.parameters import Parameters
from ..config.scenario import Campaign, Scenario
from ..environment import environment
from ..errors import InputError
from ..io.storage import write_json
from .executors import execute, worker_count
from .sampling import case_specs
from .store import CaseStore, campaign_hash
from .summary import ACCURACY, compare, error_values, markdown, regression_figures, summarize


class SweepOutcome(NamedTuple):
    """A campaign's result: its folder, summary.json content, case table and this run's counts."""

    folder: Path
    summary: dict
    ran: int  # cases run by this call (finished or failed)
    skipped: int  # cases already finished by an earlier run (--resume)
    failed: int  # cases without a result (see RESULTS_DIR/failures/)
    regressions: list[str]  # figures worse than --baseline beyond their tolerance
    cases: (
        pd.DataFrame
    )  # one row per finished case (case columns (docs/reference.md, Campaign results))


def read_baseline(path: Path) -> dict:
    """An earlier sweep's summary.json to compare with (a summary from before per-phase
    faults were keyed by name, whose ``isolation`` is the short circuit's, is read as one)."""
    if not path.is_file():
        raise InputError(path, "baseline file not found (give a summary.json of an earlier sweep)")
    try:
        data = json.loads(path.read_text())
        if "confusion" in data["isolation"]:
            data["isolation"] = {"short_circuit": data["isolation"]}
        regression_figures(data)
    except (json.JSONDecodeError, UnicodeDecodeError):
        raise InputError(
            path, "baseline is not valid JSON (give a summary.json of an earlier sweep)"
        ) from None
    except (KeyError, TypeError, AttributeError):
        raise InputError(
            path,
            "baseline lacks the summary keys errors, detection, false_alarms, "
            "isolation (give a summary.json of an earlier sweep)",
        ) from None
    return data


def open_store(
    store,
    source: Path,
    digest: str,
    meta: dict,
    definition: dict,
    base: Scenario,
    params: Parameters,
    resume: bool,
    count: int,
) -> tuple[list[int], set[int]]:
    """Open a results folder's case store (its manifest: ``meta``, the definition, base
    scenario and parameter values); the case indices still to run, and the finished ones."""
    store.open(
        source,
        digest,
        {
            **meta,
            **definition,
            "base_scenario": base.model_dump(mode="json"),
            "parameter_values": params.values(),
        },
        resume,
    )
    finished = set(store.finished())
    return [k for k in range(count) if k not in finished], finished


def run_campaign(
    campaign_path: Path,
    campaign: Campaign,
    base: Scenario,
    params: Parameters,
    output: str | Path | None,
    *,
    workers: int | None,
    client,
    resume: bool,
    baseline: str | Path | None,
    reference_summary: dict | None,
    show_progress: bool,
) -> SweepOutcome:
    """Run (or resume) ``campaign`` on ``base`` and ``params`` into ``output`` (default
    ``out/<name>``) on local ``workers`` or a Dask ``client``; its summary compared with
    ``reference_summary`` (read from ``baseline``) when given."""
    from ..report import plot_error_histograms, plot_parity

    digest = campaign_hash(campaign, base, params)
    folder = Path(output) if output else Path("out") / campaign.name
    store = CaseStore(folder)
    meta = {
        "campaign": campaign.name,
        "campaign_file": str(campaign_path),
        "campaign_hash": digest,
        "planned": campaign.cases,
        "seed": campaign.seed,
        "scenario": base.name,
        "parameters": params.source_file,
        "emaprog_version": __version__,
        "environment": environment(),
    }
    todo, finished = open_store(
        store,
        campaign_path,
        digest,
        meta,
        {"campaign_definition": campaign.model_dump(mode="json")},
        base,
        params,
        resume,
        campaign.cases,
    )
    specs = case_specs(campaign, base, params, digest, todo)
    workers = worker_count(workers, len(todo))
    start = time.perf_counter()
    counts = execute(
        specs,
        store,
        meta,
        len(todo),
        workers,
        client,
        f"sweep {campaign.name}",
        len(finished),
        show_progress,
    )
    wall_s = time.perf_counter() - start

    frame = store.read()
    if frame.empty:
        raise RuntimeError(
            f"no case of campaign '{campaign.name}' finished; the errors are in {store.failures}"
        )
    summary = {
        **meta,
        "finished": int(len(frame)),
        "failed": len(store.failed()),
        **summarize(frame, params),
    }
    summary["run"] = {
        "ran": counts["done"] + counts["failed"],
        "skipped": len(finished),
        "wall_s": wall_s,
        "workers": None if client else workers,
        "scheduler": client.scheduler.address if client else None,
    }
    errors = {q: error_values(frame, q, params) for q in ACCURACY}
    summary["figures"] = {
        "parity": plot_parity(frame, folder / "parity.png").name,
        "errors": plot_error_histograms(
            errors, {q: a.tolerance for q, a in ACCURACY.items()}, folder / "errors.png"
        ).name,
    }
    regressions = compare(summary, reference_summary) if reference_summary is not None else []
    if reference_summary is not None:
        summary["regression"] = {"baseline": str(baseline), "worse": regressions}
    write_json(folder / "summary.json", summary)
    (folder / "summary.md").write_text(markdown(summary))
    return SweepOutcome(
        folder,
        summary,
        counts["done"] + counts["failed"],
        len(finished),
        summary["failed"],
        regressions,
        frame,
    )
