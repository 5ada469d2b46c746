"""What the CLI, tests and notebooks share: check, simulate, identify, calibrate, sweep, trend.

Every function takes paths or in-memory objects, returns a typed result (a
trace as a pandas DataFrame with its units in ``attrs``, a report as a frozen
dataclass whose ``data`` is the ``report.json`` content) and writes files only
where it is given an output (``sweep`` and ``trend --simulate`` always store
their cases: that is what makes them resumable). Errors in user input raise
:class:`~emaprog.errors.InputError`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, NamedTuple

import numpy as np
import pandas as pd

from . import __version__
from .campaign.run import SweepOutcome
from .config import parameters as parameter_sets
from .config.parameters import Parameters
from .config.scenario import (
    IdentifySettings,
    Scenario,
    SpringLoad,
    load_any,
    load_scenario,
    parse_scenario,
)
from .errors import InputError
from .faults import flatten
from .identification import check_sampling, identify_trace
from .identification.defaults import resolve as resolve_settings
from .identification.objective import low_pass
from .identification.reporting import check_phase_identity, name_phases_as_recorded, report_data
from .io.recordings import check_at_rest, check_plausible
from .io.storage import (
    Trace,
    frame_of,
    read_trace,
    trace_of,
    writable_output,
    write_json,
    write_trace,
)
from .models import monitor, reference
from .models.common import inputs_from_trace

Model = Literal["reference", "monitor"]


def check(paths: list[str | Path]) -> list[str]:
    """Validate scenario, campaign, history, parameter-set and column-map files; one summary
    line each. Raises InputError."""
    from .config.yamlfile import load_mapping
    from .io.recordings import load_column_map

    lines = []
    for path in paths:
        data = load_mapping(path)
        if "electrical" in data or "mechanical" in data:
            params = parameter_sets.load(str(path))
            unit = " (a commissioned unit)" if params.spec.commissioning is not None else ""
            lines.append(f"{path}: parameter set '{params.spec.name}'{unit}")
            continue
        if "time" in data and "position" in data and "duration" not in data:
            mapping = load_column_map(path)
            lines.append(
                f"{path}: column map of {len(mapping.mapped())} channels "
                f"({', '.join(mapping.mapped())})"
            )
            continue
        kind, loaded = load_any(path)
        if kind == "campaign":
            campaign, base = loaded
            lines.append(
                f"{path}: campaign '{campaign.name}', {campaign.cases} cases on "
                f"scenario '{base.name}'"
            )
        elif kind == "history":
            history, base = loaded
            lines.append(
                f"{path}: history '{history.name}' of {history.actuator}, "
                f"{history.inspections.count} inspections on scenario '{base.name}'"
            )
        else:
            lines.append(
                f"{path}: scenario '{loaded.name}', {loaded.duration} s "
                f"{loaded.command.kind} command, parameters '{loaded.parameters}'"
            )
    return lines


def _parameters(
    name_or_path: str | Path | None,
    named_by: str | None,
    relative_to: Path | None,
    source: str | Path,
) -> Parameters:
    """``--parameters`` when given (it overrides), else the set a scenario or trace names."""
    if name_or_path is not None:
        return parameter_sets.load(str(name_or_path), source="--parameters")
    return parameter_sets.load(named_by or "default", relative_to=relative_to, source=source)


def _scenario(scenario: str | Path | Scenario | dict) -> tuple[Scenario, Path | None]:
    """A scenario from a file, a model or a mapping, with the folder its paths are relative to."""
    if isinstance(scenario, Scenario):
        return scenario, None
    if isinstance(scenario, dict):
        return parse_scenario(scenario, "scenario"), None
    path = Path(scenario)
    return load_scenario(path), path.parent


def simulate(
    scenario: str | Path | Scenario | dict,
    *,
    model: Model = "reference",
    parameters: str | Path | None = None,
    noise: bool = True,
    output: str | Path | None = None,
    plot: bool = False,
    show_progress: bool = False,
) -> pd.DataFrame:
    """Simulate a scenario on the Reference (default) or Monitor Model.

    Returns the trace as a DataFrame (trace columns (docs/reference.md, Traces); ``attrs["units"]`` per
    column, ``attrs["emaprog"]`` the provenance). With ``output`` the trace is
    also written there as Parquet (and with ``plot`` a PNG beside it).
    ``parameters`` overrides the set the scenario names.
    """
    if output is not None:
        writable_output(output, "file")
    scenario, folder = _scenario(scenario)
    params = _parameters(parameters, scenario.parameters, folder, "scenario")
    if model == "reference":
        trace = reference.simulate(scenario, params, with_noise=noise, show_progress=show_progress)
    elif model == "monitor":
        trace = monitor.simulate(scenario, params)
    else:
        raise InputError("--model", f"unknown model '{model}' (allowed: reference, monitor)")
    if output is not None:
        output = write_trace(output, trace)
        if plot:
            from .report import plot_trace

            plot_trace(trace, output.with_suffix(".png"), f"{scenario.name} ({model} model)")
    return frame_of(trace)


@dataclass(frozen=True)
class Report:
    """An identification's result: the the keys of docs/reference.md, Identification report, typed, and the whole ``report.json``."""

    estimate: dict[str, Any]  # report shape: {"friction": x, "short_circuit": {"a": x, ..}, ..}
    truth: dict[str, Any] | None  # same shape, for a simulated trace
    error: dict[str, Any] | None
    health: dict[str, str]  # fault -> nominal | incipient | degraded | inconclusive
    interval: dict[str, Any]  # estimate's shape, each estimated quantity [low, high] (90 %)
    fitness: float
    evaluations: int
    elapsed_s: float
    seed: int
    settings: dict[str, Any]
    emaprog_version: str
    data: dict[str, Any]  # everything report.json holds
    folder: Path | None  # where report.json, report.md and the figures are, if written

    @classmethod
    def from_data(cls, data: dict[str, Any], folder: Path | None = None) -> Report:
        keys = (
            "estimate",
            "truth",
            "error",
            "health",
            "interval",
            "fitness",
            "evaluations",
            "elapsed_s",
            "seed",
            "settings",
            "emaprog_version",
        )
        return cls(**{k: data[k] for k in keys}, data=data, folder=folder)


def _trace_scenario(trace: Trace, source: str | Path) -> Scenario | None:
    """The scenario a trace made by ``simulate`` carries in its metadata, if any."""
    data = (trace.metadata or {}).get("scenario")
    if data is None:
        return None
    return parse_scenario(data, f"{source} (embedded scenario)")


#: What ``identify -o`` writes: an existing one is not overwritten without ``force``.
REPORT_FILES = ("report.json", "report.md", "fit.png", "convergence.png")


def _trace_set(trace: Trace, embedded: Scenario | None, folder: Path | None) -> str | None:
    """The parameter set a simulated trace was made with: the file its provenance names
    (an absolute path, found from any folder), else the scenario's own path (relative to the
    trace's folder)."""
    if embedded is None:
        return None
    recorded = (trace.metadata or {}).get("parameter_file")
    if recorded and Path(recorded).suffix in (".yaml", ".yml") and Path(recorded).is_file():
        return str(Path(recorded).resolve())
    return embedded.parameters


def convert(
    recording: str | Path,
    columns: str | Path,
    *,
    parameters: str | Path | None = None,
    output: str | Path | None = None,
) -> pd.DataFrame:
    """A rig recording (CSV, MATLAB .mat, foreign Parquet) as a contract trace, via a column map.

    Returns the trace as a DataFrame (units in ``attrs``); with ``output`` it is
    written as contract Parquet whose provenance names the source file, its SHA-256
    and the map. ``parameters`` (default ``default``) supplies the controller
    replayed to sign an equivalent current built from phase currents.
    """
    from .io.recordings import load_column_map, read_recording

    if output is not None:
        writable_output(output, "file")
    params = _parameters(parameters, None, None, "--parameters")
    trace = read_recording(recording, load_column_map(columns), params, columns)
    if output is not None:
        write_trace(output, trace)
    return frame_of(trace)


@dataclass(frozen=True)
class Commissioned:
    """A commissioned unit: its parameter set file and what the recordings determined."""

    parameter_set: Path
    fitted: dict[str, dict[str, float]]  # name -> value, base, standard_error [SI]
    not_determined: list[str]
    degenerate: list[str]
    hinge_moments: list[float]  # [N m] per recording
    residual: float
    hinge_stiffnesses: list[float] | None = None  # [N m/rad] per recording, when fitted
    #: fitted under the base set's tolerances, barely narrowed by the recordings
    from_tolerance: list[str] = field(default_factory=list)


def _measured(
    path: Path, columns: str | Path | None, params: Parameters | None, test: Scenario | None = None
) -> Trace:
    """A contract trace file, or with a column map a rig recording read through it; ``test``:
    the scenario whose command a recording without a command channel ran (placed in time
    by its response, :mod:`emaprog.models.alignment`)."""
    from .io.recordings import load_column_map, read_recording

    if columns is None:
        return read_trace(path)
    if params is None:
        raise InputError(
            path, "a recording read through a column map needs a parameter set", "--parameters"
        )
    command_of = None
    if test is not None:
        from .models.alignment import align_command

        def command_of(time, position):
            found = align_command(test, params, time, position)
            return found.command, found.note

    return read_recording(path, load_column_map(columns), params, columns, command_of)


def _commissioning_residuals(params: Parameters) -> list:
    """The commissioning recordings' residuals of a commissioned set (``nominal_correction:
    recording``); for one that cannot be used, why (the identification then says so)."""
    import hashlib

    from .identification.objective import recording_residual

    record = params.spec.commissioning
    if record is None:
        return []
    out: list = []
    for entry in record.recordings:
        path = Path(entry.file)
        if not path.is_file():
            out.append(f"commissioning recording {entry.file} not found")
            continue
        if hashlib.sha256(path.read_bytes()).hexdigest() != entry.sha256:
            out.append(
                f"commissioning recording {entry.file} changed since commissioning (sha256 differs)"
            )
            continue
        try:
            recording = _measured(path, entry.columns, params)
        except InputError as exc:
            out.append(f"commissioning recording {entry.file} unreadable: {exc}")
            continue
        rec_inputs = inputs_from_trace(recording, params)
        out.append(
            recording_residual(
                recording,
                rec_inputs,
                params,
                entry.hinge_moment,
                str(path),
                hinge_stiffness=entry.hinge_stiffness,
            )
        )
    return out


def commission(
    recordings: Sequence[str | Path],
    output: str | Path,
    *,
    parameters: str | Path | None = None,
    columns: str | Path | None = None,
    scenario: str | Path | None = None,
    nuisances: list[str] | None = None,
    force: bool = False,
) -> Commissioned:
    """Fit a unit's own parameter set from recordings of it while healthy (docs/reference.md, Commissioning).

    ``recordings``: contract traces (Parquet) or, with ``columns``, rig recordings;
    ``scenario``: the test command of recordings without a command channel; ``nuisances``:
    the operating conditions fitted per recording, ``hinge_moment`` (always) and
    ``hinge_stiffness`` (an aerodynamic spring): both fits the spring, ``["hinge_moment"]``
    holds it at 0, None (default) fits it where the recordings show one.
    Writes ``output`` (a complete parameter set YAML with a ``commissioning`` section:
    recordings and hashes, base set, fitted values with standard errors, residuals,
    parameters held at the base value). The base set (``parameters``, default
    ``default``) is never modified. Recordings that cannot commission raise InputError.
    """
    import datetime
    import re

    from .fitting import commission as commissioning

    if not recordings:
        raise InputError("commission", "give at least one recording of the healthy unit")
    extra = sorted(set(nuisances or []) - {"hinge_moment", "hinge_stiffness"})
    if extra:
        raise InputError(
            "--nuisances",
            f"'{extra[0]}' is not fitted per recording by commissioning (allowed: "
            "hinge_moment, hinge_stiffness; the winding resistance is a unit parameter "
            "commissioning fits itself)",
        )
    spring = None if nuisances is None else "hinge_stiffness" in nuisances
    writable_output(output, "file", force, protected=True)
    base = _parameters(parameters, None, None, "--parameters")
    test = load_scenario(scenario) if scenario is not None else None
    prepared = []
    for path in map(Path, recordings):
        trace = _measured(path, columns, base, test)
        check_sampling(trace, str(path))
        check_plausible(trace, base, path)
        check_at_rest(trace, base, path)
        prepared.append(commissioning.prepare(trace, str(path), base))
    result = commissioning.fit(prepared, base, spring=spring)
    commissioning.check_explained(result, prepared)
    output = Path(output)
    name = re.sub(r"[^A-Za-z0-9_-]", "-", output.stem) or "unit"
    text = commissioning.unit_set(
        base,
        result,
        prepared,
        name,
        datetime.date.today().isoformat(),
        None if columns is None else str(columns),
    )
    output.parent.mkdir(parents=True, exist_ok=True)
    tmp = output.with_name(f".{output.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text)
        tmp.replace(output)
    finally:
        tmp.unlink(missing_ok=True)
    fitted = {
        k: {
            "value": result.values[k],
            "base": result.base[k],
            "standard_error": commissioning.reported_error(k, result.values[k], e),
        }
        for k, e in result.standard_errors.items()
    }
    return Commissioned(
        output,
        fitted,
        result.not_determined,
        result.degenerate,
        result.hinge_moments,
        result.residual,
        result.hinge_stiffnesses if any(result.stiffness_errors) else None,
        list(result.from_tolerance),
    )


class Sources(NamedTuple):
    """What an identification reads: the trace, where it came from, the scenarios and the set."""

    measured: Trace
    source: str | Path
    chosen: Scenario | None  # the --scenario
    embedded: Scenario | None  # the scenario the trace carries (a simulated trace)
    params: Parameters


def resolve_sources(
    trace: str | Path | pd.DataFrame,
    *,
    scenario: str | Path | None = None,
    parameters: str | Path | None = None,
    columns: str | Path | None = None,
) -> Sources:
    """The trace, scenarios and parameter set of an identification, each loaded once.

    The parameter set: ``parameters`` when given (it overrides), else the ``scenario``'s (its
    path relative to the scenario file), else the one the trace was simulated with (found
    from any folder, else relative to the trace's), else ``default``. A recording read
    through ``columns`` is read with that same set (its controller signs a current built
    from phase currents; its scenario places a missing command)."""
    chosen = load_scenario(scenario) if scenario is not None else None
    chosen_set = (
        _parameters(parameters, chosen.parameters, Path(str(scenario)).parent, str(scenario))
        if chosen is not None
        else None
    )
    replayed = None
    if isinstance(trace, pd.DataFrame):
        source: str | Path = "trace (DataFrame)"
        measured = trace_of(trace, source)
    else:
        source = Path(trace)
        if columns is not None:
            replayed = chosen_set or _parameters(parameters, None, None, "--parameters")
        measured = _measured(source, columns, replayed, chosen)
    embedded = _trace_scenario(measured, source)
    params = chosen_set or replayed
    if params is None:
        relative = source.parent if isinstance(source, Path) else None
        params = _parameters(
            parameters,
            _trace_set(measured, embedded, relative),
            relative,
            f"{source} (embedded scenario)",
        )
    return Sources(measured, source, chosen, embedded, params)


def identify(
    trace: str | Path | pd.DataFrame,
    *,
    scenario: str | Path | None = None,
    parameters: str | Path | None = None,
    columns: str | Path | None = None,
    output: str | Path | None = None,
    inspection: dict | None = None,
    nuisances: list[str] | None = None,
    force: bool = False,
    show_progress: bool = False,
) -> Report:
    """Identify the faults in a measured trace (a Parquet path or a DataFrame).

    Settings come from ``scenario`` when given, else from the scenario embedded in
    the trace, else the defaults; the parameter set from ``parameters`` when given
    (it overrides), else from that same scenario, else ``default``. Truth and
    error are reported when the trace carries its scenario (a simulated trace).
    ``inspection`` ({"actuator": ID, "usage": hours}) tags the report for
    ``emaprog trend``. ``nuisances`` overrides ``identify.nuisances`` (omitted there: the
    hinge moment and resistance factor for a real unit, none for a twin experiment;
    :mod:`emaprog.identification.defaults`). A scenario's ``load`` applies to a trace that
    carries it or, for a recording, only when the hinge moment is not estimated (the
    report's ``load`` says which). ``columns`` (a column map YAML) reads ``trace`` as a rig
    recording (CSV, MATLAB .mat, foreign Parquet; :mod:`emaprog.io.recordings`).
    With ``output``, report.json, report.md and the figures are written there.
    """
    if output is not None:
        writable_output(output, "folder", force, protected=REPORT_FILES)
    measured, source, chosen, embedded, params = resolve_sources(
        trace, scenario=scenario, parameters=parameters, columns=columns
    )
    basis = chosen or embedded
    resolved = resolve_settings(
        basis.identify if basis is not None else IdentifySettings(),
        measured.metadata,
        params,
        nuisances,
    )
    settings = resolved.settings
    check_sampling(measured, str(source))
    check_plausible(measured, params, source)
    check_at_rest(measured, params, source)
    load, load_note = _load_of(embedded, chosen, settings)
    inp = inputs_from_trace(measured, params, load)
    recordings = (
        _commissioning_residuals(params) if settings.nominal_correction == "recording" else []
    )
    result = identify_trace(
        measured, inp, params, settings, show_progress=show_progress, recordings=recordings
    )

    data = report_data(
        result,
        settings=settings,
        params=params,
        truth=flatten(embedded.faults) if embedded is not None else None,
        load=load,
        load_note=load_note,
        notes=resolved.notes,
        source=str(source),
        scenario_name=basis.name if basis is not None else None,
        inspection=inspection,
    )
    name_phases_as_recorded(data, (measured.metadata or {}).get("phase_identity"))
    check_phase_identity(data, params)
    if output is None:
        return Report.from_data(data)
    folder = Path(output)
    _write_report(data, result, measured, folder)
    return Report.from_data(data, folder)


def _write_report(data: dict, result, measured: Trace, folder: Path) -> None:
    """report.json, report.md and the figures of an identification, into ``folder``."""
    from .report import plot_convergence, plot_fit, report_markdown

    folder.mkdir(parents=True, exist_ok=True)
    objective = result.objective
    identified = objective.simulate(result.estimate)
    residual = objective.target.current - objective.instants.sample(
        low_pass(identified["current"], objective.filter_width)
    )
    floor = result.confidence.floor.sigma["current"] / np.sqrt(objective.measured_width)
    figures = {
        "fit": plot_fit(
            measured,
            identified,
            objective.measured_width,
            objective.filter_width,
            folder / "fit.png",
            residual,
            floor,
        ),
        "convergence": plot_convergence(result.logbook, folder / "convergence.png"),
    }
    data["figures"] = {name: path.name for name, path in figures.items()}
    write_json(folder / "report.json", data)
    (folder / "report.md").write_text(report_markdown(data))


def _load_of(embedded: Scenario | None, chosen: Scenario | None, settings: IdentifySettings):
    """The load the Monitor is driven with, and why: the trace's own scenario's (a simulated
    trace knows its load); for a recording, a ``--scenario``'s when the hinge moment is not
    estimated, and its aerodynamic spring alone when the hinge moment is estimated and the
    spring is not (a rig's programmed spring rate, its constant part unknown); the report's
    ``load`` says which (a scenario given for its settings never adds a load silently)."""
    if embedded is not None:
        return embedded.load, "the trace's own scenario"
    estimated = settings.nuisances or []
    if chosen is None or chosen.load.kind == "none":
        return None, (
            "none: the recording's hinge moment is estimated (nuisance hinge_moment)"
            if "hinge_moment" in estimated
            else "none (no scenario load; hinge moment not estimated)"
        )
    spring = chosen.load if isinstance(chosen.load, SpringLoad) else None
    if "hinge_moment" in estimated and spring and "hinge_stiffness" not in estimated:
        return spring.model_copy(update={"torque": 0.0}), (
            f"the scenario's aerodynamic spring, {spring.stiffness:g} N m/rad, stated "
            "for this recording; its constant part is estimated (nuisance hinge_moment)"
        )
    if "hinge_moment" in estimated:
        return None, (
            f"the scenario's {chosen.load.kind} load is not applied to the recording: "
            "its hinge moment is estimated (nuisance hinge_moment); to state a known "
            "load instead, identify with --nuisances none or resistance_factor"
        )
    return chosen.load, "the --scenario's load, stated for this recording"


def verdict_text(report: Report) -> str:
    """A few lines a person reads on the terminal after ``identify``."""
    from .report import identification_summary

    return identification_summary(report.data)


@dataclass(frozen=True)
class Calibration:
    """A calibration's result (docs/reference.md, Calibration): the ``calibration.json`` content and the calibrated set."""

    eccentricity_gain: float  # [-] c of Z = c zeta
    r_squared: float
    commutation_loss: float  # [s/rad]
    signature_error: dict[str, float]  # per fault (docs/reference.md, The models)
    parameter_set: Path  # the calibrated, complete parameter set (parameters.yaml)
    data: dict[str, Any]
    folder: Path


def calibrate(
    parameters: str | Path = "default",
    output: str | Path = Path("out") / "calibration",
) -> Calibration:
    """Fit the Monitor's nominal equivalents and Z-zeta gain to the Reference Model (docs/reference.md, Calibration).

    Writes ``calibration.json``, ``z_vs_zeta.png`` and ``parameters.yaml`` (the input
    set with the calibrated monitor values and a ``changes`` record: complete and
    loadable wherever a set is accepted) into ``output``. The input set is never
    modified; to ship the calibrated values, copy ``parameters.yaml`` over the
    shipped file (docs/reference.md, "Calibration").
    """
    import datetime

    from .fitting import calibration
    from .report import plot_calibration

    params = parameter_sets.load(str(parameters), source="--parameters")
    result = calibration.calibrate(params)
    folder = Path(output)
    folder.mkdir(parents=True, exist_ok=True)
    result["figure"] = plot_calibration(result, folder / "z_vs_zeta.png").name
    result["emaprog_version"] = __version__
    today = datetime.date.today().isoformat()
    (folder / "parameters.yaml").write_text(
        calibration.calibrated_set(params.source_file, result, today)
    )
    result["parameter_set"] = "parameters.yaml"
    write_json(folder / "calibration.json", result)
    return Calibration(
        result["eccentricity_gain"],
        result["r_squared"],
        result["commutation_loss"],
        result["signature_error"],
        folder / "parameters.yaml",
        result,
        folder,
    )


def sweep(
    campaign_path: str | Path,
    output: str | Path | None = None,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    baseline: str | Path | None = None,
    show_progress: bool = False,
) -> SweepOutcome:
    """Run (or resume) a Monte-Carlo campaign and write its case dataset and summary (docs/reference.md, Campaign YAML and Campaign results).

    Cases run on ``workers`` local processes (default: all cores; 1 runs them in
    this process) or, with ``scheduler``, on a Dask cluster. Each finished case
    is on disk at once; Ctrl-C raises :class:`emaprog.campaign.cases.Interrupted`
    after stopping the workers. With ``baseline`` the summary is compared with an earlier one.
    """
    from .campaign import cases as campaigns
    from .campaign.run import read_baseline, run_campaign
    from .config.scenario import load_campaign

    campaign_path = Path(campaign_path)
    campaign, base = load_campaign(campaign_path)
    params = campaigns.load_parameters(campaign_path, campaign, base)
    reference_summary = read_baseline(Path(baseline)) if baseline is not None else None
    client = campaigns.connect(scheduler) if scheduler is not None else None
    try:
        return run_campaign(
            campaign_path,
            campaign,
            base,
            params,
            output,
            workers=workers,
            client=client,
            resume=resume,
            baseline=baseline,
            reference_summary=reference_summary,
            show_progress=show_progress,
        )
    finally:
        if client is not None:
            client.close()


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
        raise InputError(
            history_path,
            "is a history YAML: pass --simulate to simulate and identify its inspections",
        )
    raise InputError(
        history_path,
        "give a Parquet history table, a folder of report.json, or "
        "a synthetic history YAML with --simulate",
    )


@dataclass(frozen=True)
class Trend:
    """A prognosis: per fault its growth law, detection and RUL (``trend.json`` is ``data``)."""

    actuator: str
    faults: dict[str, dict[str, Any]]  # fault -> status, law, rul {median, low, high} [h], ...
    data: dict[str, Any]
    folder: Path


def trend(
    history_path: str | Path,
    output: str | Path | None = None,
    *,
    simulate: bool = False,
    law: str = "auto",
    parameters: str = "default",
    workers: int | None = None,
    resume: bool = False,
    show_progress: bool = False,
) -> Trend:
    """Fit each fault's growth over usage and predict its remaining useful life.

    ``history_path`` is a Parquet table, a folder of ``report.json`` files, or
    (with ``simulate``) a synthetic history YAML whose inspections are simulated
    and identified first, resumably, under ``OUTPUT/inspections/``. Writes
    ``trend.json``, ``trend.md`` and ``trend.png``; see :mod:`emaprog.prognosis.fit`.
    """
    from .campaign import cases as campaigns
    from .campaign.run import open_store
    from .config.scenario import load_history
    from .prognosis import history as histories
    from .prognosis.analysis import analyse
    from .prognosis.fit import LAWS
    from .report import plot_trend, trend_markdown

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
        meta = {
            "history": history.name,
            "history_file": str(history_path),
            "history_hash": digest,
            "actuator": history.actuator,
            "emaprog_version": __version__,
        }
        todo, finished = open_store(
            store,
            history_path,
            digest,
            meta,
            {"history_definition": history.model_dump(mode="json")},
            base,
            params,
            resume,
            history.inspections.count,
        )
        specs = histories.inspection_specs(history, base, params, digest, todo)
        workers = campaigns.worker_count(workers, len(todo))
        campaigns.execute(
            specs,
            store,
            meta,
            len(todo),
            workers,
            None,
            f"inspections of {history.actuator}",
            len(finished),
            show_progress,
        )
        if len(store.finished()) < 3:
            raise RuntimeError(f"fewer than 3 inspections identified; errors in {store.failures}")
        table = histories.from_cases(history, params, store, str(history_path))
    else:
        params = parameter_sets.load(parameters)
        table = (
            histories.read_reports(history_path)
            if kind == "reports"
            else histories.read_table(history_path)
        )
    result = analyse(table, params, law)
    folder.mkdir(parents=True, exist_ok=True)
    result["figure"] = plot_trend(result, folder / "trend.png").name
    write_json(folder / "trend.json", result)
    (folder / "trend.md").write_text(trend_markdown(result))
    return Trend(result["actuator"], result["faults"], result, folder)
