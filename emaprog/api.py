"""What the CLI, tests and notebooks share: check, simulate, identify, calibrate, sweep."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from . import __version__
from . import parameters as parameter_sets
from .errors import InputError
from .faults import flatten, nested
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
        else:
            lines.append(f"{path}: scenario '{loaded.name}', {loaded.duration} s "
                         f"{loaded.command.kind} command, parameters '{loaded.parameters}'")
    return lines


def scenario_parameters(scenario: Scenario, scenario_path: str | Path | None):
    """The parameter set a scenario names, resolved next to its file."""
    base = Path(scenario_path).parent if scenario_path is not None else None
    return parameter_sets.load(scenario.parameters, relative_to=base)


def simulate_scenario(scenario: Scenario, params, model: Model = "reference",
                      with_noise: bool = True) -> Trace:
    if model == "reference":
        return reference.simulate(scenario, params, with_noise=with_noise)
    if model == "monitor":
        return monitor.simulate(scenario, params)
    raise InputError("--model", f"unknown model '{model}' (allowed: reference, monitor)")


def simulate(scenario_path: str | Path, output: str | Path | None = None,
             model: Model = "reference", plot: bool = False) -> tuple[Path, Path | None]:
    """Simulate a scenario file and write its trace (and optional PNG beside it)."""
    scenario = load_scenario(scenario_path)
    params = scenario_parameters(scenario, scenario_path)
    trace = simulate_scenario(scenario, params, model)
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
             output: str | Path | None = None, show_progress: bool = True) -> tuple[dict, Path]:
    """Identify the faults in a measured trace and write report.json, report.md and figures.

    Settings and parameter set come from ``scenario_path`` when given, else
    from the scenario embedded in the trace, else the defaults. Truth and error
    are reported when the trace carries its scenario (a simulated trace).
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
        "short_circuit_phase": verdicts.faulty_phase(result.estimate),
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
