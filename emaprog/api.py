"""What the CLI, tests and notebooks share: check, simulate, identify, calibrate, sweep."""

from __future__ import annotations

from pathlib import Path
from typing import Literal, NamedTuple

from . import __version__
from . import parameters as parameter_sets
from .errors import InputError
from .faults import flatten, nested, worst_phase
from .identification import check_sampling, identify_trace
from .identification import result as verdicts
from .models import monitor, reference
from .models.common import inputs_from_trace
from .report import (identification_summary, plot_calibration, plot_convergence, plot_fit, plot_trace,
                     report_markdown, write_json)
from .scenario import IdentifySettings, Scenario, load_any, load_scenario, parse_scenario
from .storage import Trace, read_trace, write_trace

Model = Literal["reference", "monitor"]


def check(paths: list[str | Path]) -> list[str]:
    """Validate scenario and campaign files; one summary line each. Raises InputError."""
    lines = []
    for path in paths:
        kind, loaded = load_any(path)
        if kind == "campaign":
            campaign, base = loaded
            lines.append(f"{path}: campaign '{campaign.name}', {campaign.cases} cases on "
                         f"scenario '{base.name}'")
        elif kind == "history":
            history, base = loaded
            lines.append(f"{path}: history '{history.name}' of {history.actuator}, "
                         f"{history.inspections.count} inspections on scenario '{base.name}'")
        else:
            lines.append(f"{path}: scenario '{loaded.name}', {loaded.duration} s "
                         f"{loaded.command.kind} command, parameters '{loaded.parameters}'")
    return lines


def scenario_parameters(scenario: Scenario, scenario_path: str | Path | None):
    """The parameter set a scenario names, resolved next to its file."""
    base = Path(scenario_path).parent if scenario_path is not None else None
    return parameter_sets.load(scenario.parameters, relative_to=base)


def simulate_scenario(scenario: Scenario, params, model: Model = "reference",
                      with_noise: bool = True, show_progress: bool = False) -> Trace:
    if model == "reference":
        return reference.simulate(scenario, params, with_noise=with_noise,
                                  show_progress=show_progress)
    if model == "monitor":
        return monitor.simulate(scenario, params)
    raise InputError("--model", f"unknown model '{model}' (allowed: reference, monitor)")


def simulate(scenario_path: str | Path, output: str | Path | None = None,
             model: Model = "reference", plot: bool = False,
             show_progress: bool = True) -> tuple[Path, Path | None]:
    """Simulate a scenario file and write its trace (and optional PNG beside it)."""
    scenario = load_scenario(scenario_path)
    params = scenario_parameters(scenario, scenario_path)
    trace = simulate_scenario(scenario, params, model, show_progress=show_progress)
    output = Path(output) if output else Path("out") / f"{scenario.name}-{model}.parquet"
    write_trace(output, trace)
    figure = None
    if plot:
        figure = plot_trace(trace, output.with_suffix(".png"),
                            f"{scenario.name} ({model} model)")
    return output, figure


def _trace_scenario(trace: Trace, source: Path) -> Scenario | None:
    """The scenario a trace made by ``simulate`` carries in its metadata, if any."""
    data = (trace.metadata or {}).get("scenario")
    if data is None:
        return None
    return parse_scenario(data, f"{source} (embedded scenario)")


def identify(trace_path: str | Path, scenario_path: str | Path | None = None,
             output: str | Path | None = None, show_progress: bool = True,
             inspection: dict | None = None) -> tuple[dict, Path]:
    """Identify the faults in a measured trace and write report.json, report.md and figures.

    Settings and parameter set come from ``scenario_path`` when given, else
    from the scenario embedded in the trace, else the defaults. Truth and error
    are reported when the trace carries its scenario (a simulated trace).
    ``inspection`` ({"actuator": ID, "usage": hours}) tags the report for
    ``emaprog trend``.
    """
    trace_path = Path(trace_path)
    trace = read_trace(trace_path)
    embedded = _trace_scenario(trace, trace_path)
    scenario = load_scenario(scenario_path) if scenario_path is not None else None
    if scenario is not None:
        params = scenario_parameters(scenario, scenario_path)
    elif embedded is not None:
        params = parameter_sets.load(embedded.parameters, relative_to=trace_path.parent,
                                     source=f"{trace_path} (embedded scenario)")
    else:
        params = parameter_sets.load("default")
    basis = scenario or embedded
    settings = basis.identify if basis is not None else IdentifySettings()
    check_sampling(trace, params, str(trace_path))
    inp = inputs_from_trace(trace, basis.load if basis is not None else None)
    result = identify_trace(trace, inp, params, settings, show_progress=show_progress)

    truth = flatten(embedded.faults) if embedded is not None else None
    error = verdicts.errors(result.estimate, truth) if truth is not None else None
    report = {
        "estimate": nested(result.estimate),
        "truth": nested(truth) if truth is not None else None,
        "error": nested(error) if error is not None else None,
        "health": verdicts.health(result.estimate, settings.estimate, params),
        "short_circuit_phase": worst_phase(result.estimate),
        "fitness": result.fitness,
        "ga": {"estimate": nested(result.ga_estimate), "fitness": result.ga_fitness,
               "generations": result.generations, "stopped_by": result.stopped_by,
               "refined": result.refined, "logbook": result.logbook},
        "evaluations": result.evaluations,
        "elapsed_s": result.elapsed_s,
        "seed": settings.ga.seed,
        "settings": settings.model_dump(mode="json"),
        "trace": str(trace_path),
        "scenario": basis.name if basis is not None else None,
        "parameters": params.source_file,
        "inspection": inspection,
        "emaprog_version": __version__,
    }
    folder = Path(output) if output else Path("out") / f"{trace_path.stem}-report"
    folder.mkdir(parents=True, exist_ok=True)
    identified = result.objective.simulate(result.estimate)
    figures = {
        "fit": plot_fit(trace, identified, result.objective.filter_width, folder / "fit.png"),
        "convergence": plot_convergence(result.logbook, folder / "convergence.png"),
    }
    report["figures"] = {name: path.name for name, path in figures.items()}
    write_json(folder / "report.json", report)
    (folder / "report.md").write_text(report_markdown(report))
    return report, folder


def verdict_text(report: dict) -> str:
    """A few lines a person reads on the terminal after ``identify``."""
    return identification_summary(report)


def calibrate(parameters: str | Path = "default", output: str | Path | None = None,
              write: bool = True) -> tuple[dict, Path]:
    """Fit the Monitor's nominal equivalents and Z-zeta gain; write calibration.json + figure.

    With ``write`` the calibrated values go into the parameter file itself.
    """
    from . import calibration

    params = parameter_sets.load(str(parameters))
    result = calibration.calibrate(params)
    folder = Path(output) if output else Path("out") / "calibration"
    folder.mkdir(parents=True, exist_ok=True)
    result["figure"] = plot_calibration(result, folder / "z_vs_zeta.png").name
    result["emaprog_version"] = __version__
    write_json(folder / "calibration.json", result)
    if write:
        calibration.write_into(params.source_file, result)
    return result, folder


class SweepOutcome(NamedTuple):
    folder: Path
    summary: dict
    ran: int  # cases run by this call (finished or failed)
    skipped: int  # cases already finished by an earlier run (--resume)
    failed: int  # cases without a result (see RESULTS_DIR/failures/)
    regressions: list[str]  # figures worse than --baseline beyond their tolerance


def _read_baseline(path: Path) -> dict:
    import json

    from .campaign_summary import regression_figures

    if not path.is_file():
        raise InputError(path, "baseline file not found (give a summary.json of an earlier sweep)")
    try:
        data = json.loads(path.read_text())
        regression_figures(data)
    except (json.JSONDecodeError, UnicodeDecodeError):
        raise InputError(path, "baseline is not valid JSON (give a summary.json of an earlier sweep)") from None
    except (KeyError, TypeError, AttributeError):
        raise InputError(path, "baseline lacks the summary keys errors, detection, false_alarms, "
                         "isolation (give a summary.json of an earlier sweep)") from None
    return data


def sweep(campaign_path: str | Path, output: str | Path | None = None, workers: int | None = None,
          scheduler: str | None = None, resume: bool = False, baseline: str | Path | None = None,
          show_progress: bool = True) -> SweepOutcome:
    """Run (or resume) a Monte-Carlo campaign and write its case dataset and summary (SPEC 6).

    Cases run on ``workers`` local processes (default: all cores; 1 runs them in
    this process) or, with ``scheduler``, on a Dask cluster. Each finished case
    is on disk at once; Ctrl-C raises :class:`emaprog.campaign.Interrupted`
    after stopping the workers. With ``baseline`` the summary is compared with an earlier one.
    """
    from . import campaign as campaigns
    from .scenario import load_campaign

    campaign_path = Path(campaign_path)
    campaign, base = load_campaign(campaign_path)
    params = campaigns.load_parameters(campaign_path, campaign, base)
    reference_summary = _read_baseline(Path(baseline)) if baseline is not None else None
    client = campaigns.connect(scheduler) if scheduler is not None else None
    try:
        return _sweep(campaign_path, campaign, base, params, output, workers, client,
                      resume, baseline, reference_summary, show_progress)
    finally:
        if client is not None:
            client.close()


def _sweep(campaign_path: Path, campaign, base, params, output, workers, client, resume,
           baseline, reference_summary, show_progress) -> SweepOutcome:
    import time

    from . import campaign as campaigns
    from .campaign_summary import ACCURACY, compare, error_values, markdown, summarize
    from .report import plot_error_histograms, plot_parity

    digest = campaigns.campaign_hash(campaign, base, params)
    folder = Path(output) if output else Path("out") / campaign.name
    store = campaigns.CaseStore(folder)
    meta = {
        "campaign": campaign.name, "campaign_file": str(campaign_path), "campaign_hash": digest,
        "planned": campaign.cases, "seed": campaign.seed, "scenario": base.name,
        "parameters": params.source_file, "emaprog_version": __version__,
    }
    store.open(campaign_path, digest, {**meta, "campaign_definition": campaign.model_dump(mode="json"),
                                       "base_scenario": base.model_dump(mode="json"),
                                       "parameter_values": params.values()}, resume)
    finished = store.finished()
    todo = [k for k in range(campaign.cases) if k not in finished]
    specs = campaigns.case_specs(campaign, base, params, digest, todo)
    workers = campaigns.worker_count(workers, len(todo))
    start = time.perf_counter()
    counts = campaigns.execute(specs, store, meta, len(todo), workers, client,
                               f"sweep {campaign.name}", len(finished), show_progress)
    wall_s = time.perf_counter() - start

    frame = store.read()
    if frame.empty:
        raise RuntimeError(f"no case of campaign '{campaign.name}' finished; the errors are in "
                           f"{store.failures}")
    summary = {**meta, "finished": int(len(frame)), "failed": len(store.failed()),
               **summarize(frame, params)}
    summary["run"] = {"ran": counts["done"] + counts["failed"], "skipped": len(finished),
                      "wall_s": wall_s, "workers": None if client else workers,
                      "scheduler": client.scheduler.address if client else None}
    errors = {q: error_values(frame, q, params) for q in ACCURACY}
    summary["figures"] = {
        "parity": plot_parity(frame, folder / "parity.png").name,
        "errors": plot_error_histograms(errors, {q: a.tolerance for q, a in ACCURACY.items()},
                                        folder / "errors.png").name,
    }
    regressions = compare(summary, reference_summary) if reference_summary is not None else []
    if reference_summary is not None:
        summary["regression"] = {"baseline": str(baseline), "worse": regressions}
    write_json(folder / "summary.json", summary)
    (folder / "summary.md").write_text(markdown(summary))
    return SweepOutcome(folder, summary, counts["done"] + counts["failed"], len(finished),
                        summary["failed"], regressions)


def _history_source(history_path: Path, simulate: bool) -> str:
    """Which kind of history a path is: 'synthetic', 'reports' or 'table'."""
    if simulate:
        if history_path.suffix not in (".yaml", ".yml"):
            raise InputError(history_path, "--simulate takes a synthetic history YAML")
        return "synthetic"
    if history_path.is_dir():
        return "reports"
    if history_path.suffix == ".parquet":
        if not history_path.is_file():
            raise InputError(history_path, "history table not found")
        return "table"
    if history_path.suffix in (".yaml", ".yml"):
        raise InputError(history_path, "is a history YAML: pass --simulate to simulate and "
                         "identify its inspections")
    raise InputError(history_path, "give a Parquet history table, a folder of report.json, or "
                     "a synthetic history YAML with --simulate")


def trend(history_path: str | Path, output: str | Path | None = None, simulate: bool = False,
          law: str = "auto", parameters: str = "default", workers: int | None = None,
          resume: bool = False, show_progress: bool = True) -> tuple[dict, Path]:
    """Fit each fault's growth over usage and predict its remaining useful life.

    ``history_path`` is a Parquet table, a folder of ``report.json`` files, or
    (with ``simulate``) a synthetic history YAML whose inspections are simulated
    and identified first, resumably, under ``OUTPUT/inspections/``. Writes
    ``trend.json``, ``trend.md`` and ``trend.png``; see :mod:`emaprog.prognosis`.
    """
    from . import campaign as campaigns
    from . import history as histories
    from .prognosis import LAWS
    from .report import plot_trend, trend_markdown
    from .scenario import load_history
    from .trend import analyse

    if law not in ("auto", *LAWS):
        raise InputError("--law", f"unknown law '{law}' (allowed: auto, {', '.join(LAWS)})")
    history_path = Path(history_path)
    kind = _history_source(history_path, simulate)
    folder = Path(output) if output else Path("out") / f"{history_path.stem}-trend"
    if kind == "synthetic":
        history, base = load_history(history_path)
        params = campaigns.load_parameters(history_path, history, base)
        digest = histories.history_hash(history, base, params)
        store = campaigns.CaseStore(folder / "inspections")
        meta = {"history": history.name, "history_file": str(history_path), "history_hash": digest,
                "actuator": history.actuator, "emaprog_version": __version__}
        store.open(history_path, digest, {**meta, "history_definition": history.model_dump(mode="json"),
                                          "base_scenario": base.model_dump(mode="json"),
                                          "parameter_values": params.values()}, resume)
        finished = store.finished()
        todo = [k for k in range(history.inspections.count) if k not in finished]
        specs = histories.inspection_specs(history, base, params, digest, todo)
        workers = campaigns.worker_count(workers, len(todo))
        campaigns.execute(specs, store, meta, len(todo), workers, None,
                          f"inspections of {history.actuator}", len(finished), show_progress)
        if len(store.finished()) < 3:
            raise RuntimeError(f"fewer than 3 inspections identified; errors in {store.failures}")
        table = histories.from_cases(history, params, store, str(history_path))
    else:
        params = parameter_sets.load(parameters)
        table = (histories.read_reports(history_path) if kind == "reports"
                 else histories.read_table(history_path))
    result = analyse(table, params, law)
    folder.mkdir(parents=True, exist_ok=True)
    result["figure"] = plot_trend(result, folder / "trend.png").name
    write_json(folder / "trend.json", result)
    (folder / "trend.md").write_text(trend_markdown(result))
    return result, folder
