"""What the CLI, tests and notebooks share: check, simulate, identify, calibrate, sweep."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from . import parameters as parameter_sets
from .errors import InputError
from .models import monitor, reference
from .report import plot_trace
from .scenario import Scenario, load_any, load_scenario
from .storage import Trace, write_trace

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
