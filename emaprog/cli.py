"""Command line: parse, delegate to :mod:`emaprog.api`, say where results went.

Exit codes: 0 success; 1 internal error; 2 invalid input; 3 sweep regressed
against its baseline.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from pathlib import Path
from typing import Annotated

import typer

from . import __version__
from .errors import InputError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="emaprog: fault identification and prognostics for flight-control EMAs.",
    context_settings={"help_option_names": ["-h", "--help"]},
)

EXIT_INPUT = 2
EXIT_INTERNAL = 1
EXIT_REGRESSED = 3

# ------------------------------------------------------------ shared options
OutputDir = Annotated[Path | None, typer.Option("--output", "-o", help="Output folder.")]
ScenarioOption = Annotated[
    Path | None,
    typer.Option(
        "--scenario",
        "-s",
        help="Scenario YAML whose identify: block and parameter set to "
        "use; for a recording without a command channel, its test command.",
    ),
]
ParametersOption = Annotated[
    str,
    typer.Option("--parameters", "-p", help="Parameter set: shipped name or path to a YAML file."),
]
ColumnsOption = Annotated[
    Path | None,
    typer.Option(
        "--columns",
        "-c",
        help="Column map YAML: read the trace as a rig recording (CSV, .mat, foreign Parquet).",
    ),
]
ForceOption = Annotated[
    bool,
    typer.Option("--force", help="Overwrite an existing report or unit file (refused otherwise)."),
]
ParametersOverride = Annotated[
    str | None,
    typer.Option(
        "--parameters",
        "-p",
        help="Parameter set (shipped name or YAML path); overrides the set the scenario or trace names.",
    ),
]


def _fail(code: int, message: str) -> None:
    typer.echo(f"emaprog: {message}", err=True)
    raise typer.Exit(code)


def guarded(func: Callable) -> Callable:
    """Map InputError to exit 2 with one message; anything else to exit 1."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except InputError as exc:
            _fail(EXIT_INPUT, f"invalid input: {exc}")
        except KeyboardInterrupt as exc:
            code = getattr(exc, "exit_code", 130)  # the shell's 128 + signal (campaign runs)
            _fail(code, f"interrupted: {exc}" if str(exc) else "interrupted")
        except typer.Exit:
            raise
        except Exception as exc:  # noqa: BLE001 - the last line of defence
            if os.environ.get("EMAPROG_DEBUG"):
                raise
            _fail(
                EXIT_INTERNAL,
                f"internal error: {type(exc).__name__}: {exc} "
                "(set EMAPROG_DEBUG=1 for the traceback)",
            )

    return wrapper


def _say_if_compiling() -> None:
    """The first run after an install compiles the numba kernels (seconds): say so once."""
    cache = Path(__file__).resolve().parent / "kernels" / "__pycache__"
    if not any(cache.glob("monitor.*.nbi")):
        typer.echo(
            "compiling the numerical kernels once (numba; cached for later runs)...", err=True
        )


def _version(value: bool):
    if value:
        typer.echo(f"emaprog {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,
):
    """emaprog: fault identification and prognostics for flight-control EMAs."""


@app.command(epilog="Example: emaprog check configs/*.yaml campaigns/*.yaml")
@guarded
def check(
    files: Annotated[
        list[Path],
        typer.Argument(help="Scenario, campaign, history, parameter-set or column-map YAML files."),
    ],
):
    """Validate scenario, campaign, history, parameter-set and column-map files; run nothing."""
    from . import api

    failures = 0
    for path in files:
        try:
            for line in api.check([path]):
                typer.echo(f"ok  {line}")
        except InputError as exc:
            failures += 1
            typer.echo(f"emaprog: invalid input: {exc}", err=True)
    if failures:
        raise typer.Exit(EXIT_INPUT)


@app.command(
    epilog="Example: emaprog simulate configs/fig10-multiple-faults.yaml -o out/fig10.parquet --plot"
)
@guarded
def simulate(
    scenario: Annotated[Path, typer.Argument(help="Scenario YAML.")],
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="Trace Parquet to write.")
    ] = None,
    model: Annotated[str, typer.Option("--model", "-m", help="reference | monitor")] = "reference",
    plot: Annotated[
        bool, typer.Option("--plot", help="Also write a PNG beside the trace.")
    ] = False,
    parameters: ParametersOverride = None,
):
    """Simulate a scenario on the Reference (default) or Monitor Model and write its trace."""
    from . import api

    _say_if_compiling()
    from .config.scenario import load_scenario

    if model not in ("reference", "monitor"):
        raise InputError("--model", f"unknown model '{model}' (allowed: reference, monitor)")
    output = output or Path("out") / f"{load_scenario(scenario).name}-{model}.parquet"
    api.simulate(
        scenario,
        model="monitor" if model == "monitor" else "reference",
        parameters=parameters,
        output=output,
        plot=plot,
        show_progress=True,
    )
    typer.echo(f"trace: {output}")
    if plot:
        typer.echo(f"plot: {output.with_suffix('.png')}")


@app.command(
    epilog="Example: emaprog convert rig/run-12.csv --columns rig/logger.yaml -o out/run-12.parquet"
)
@guarded
def convert(
    recording: Annotated[Path, typer.Argument(help="Rig recording: CSV, MATLAB .mat or Parquet.")],
    columns: Annotated[Path, typer.Option("--columns", "-c", help="Column map YAML.")],
    output: Annotated[
        Path | None,
        typer.Option(
            "--output", "-o", help="Trace Parquet to write (default out/RECORDING.parquet)."
        ),
    ] = None,
    parameters: ParametersOverride = None,
):
    """Convert a rig recording into a contract trace (SI units, equivalent current, provenance)."""
    from . import api

    output = output or Path("out") / f"{recording.stem}.parquet"
    frame = api.convert(recording, columns, parameters=parameters, output=output)
    meta = frame.attrs["emaprog"]
    typer.echo(
        f"{len(frame)} samples at {meta['sample_rate']:.6g} Hz; equivalent current: "
        f"{meta['equivalent_current']}"
    )
    typer.echo(f"trace: {output}")


@app.command(
    epilog="Example: emaprog commission rig/healthy-1.parquet rig/healthy-2.parquet "
    "-o units/ema-7.yaml"
)
@guarded
def commission(
    recordings: Annotated[
        list[Path],
        typer.Argument(help="Recordings of the unit while healthy (the standard test command)."),
    ],
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Unit parameter set YAML to write.")
    ],
    parameters: Annotated[
        str | None,
        typer.Option(
            "--parameters",
            "-p",
            help="Base parameter set (shipped name or YAML path); default: default.",
        ),
    ] = None,
    columns: ColumnsOption = None,
    scenario: Annotated[
        Path | None,
        typer.Option(
            "--scenario",
            "-s",
            help="The test command as a scenario, for recordings without a "
            "command channel (placed in time by the response).",
        ),
    ] = None,
    nuisances: Annotated[
        str | None,
        typer.Option(
            "--nuisances",
            help="Operating conditions fitted per recording: hinge_moment (always) and "
            "hinge_stiffness (an aerodynamic spring). Default: the spring where the "
            "recordings show one; 'hinge_moment' alone holds it at 0, both always fit it.",
        ),
    ] = None,
    force: ForceOption = False,
):
    """Fit a unit's own parameter set (inertias, friction, viscous, R, k_e, L, stiffness)."""
    from . import api

    _say_if_compiling()

    unit = api.commission(
        recordings,
        output,
        parameters=parameters,
        columns=columns,
        scenario=scenario,
        nuisances=_nuisance_list(nuisances),
        force=force,
    )
    for name, entry in unit.fitted.items():
        typer.echo(
            f"  {name:24s} {entry['value']:.5g} (base {entry['base']:.5g}, "
            f"x{entry['value'] / entry['base']:.3f} +- {entry['standard_error'] / entry['base']:.1%})"
        )
    if unit.not_determined:
        typer.echo(f"held at the base value (not determined): {', '.join(unit.not_determined)}")
    if unit.from_tolerance:
        typer.echo(
            "within the build tolerances, barely narrowed by the recordings: "
            + ", ".join(unit.from_tolerance)
        )
    for line in unit.degenerate:
        typer.echo(f"weakly determined: {line}")
    typer.echo(
        "hinge moment per recording [N m]: " + ", ".join(f"{h:.1f}" for h in unit.hinge_moments)
    )
    if unit.hinge_stiffnesses is not None:
        typer.echo(
            "aerodynamic spring per recording [N m/rad]: "
            + ", ".join(f"{k:.0f}" for k in unit.hinge_stiffnesses)
        )
    typer.echo(f"unit: {unit.parameter_set}")


@app.command(epilog="Example: emaprog identify out/fig10.parquet -o out/fig10-report")
@guarded
def identify(
    trace: Annotated[
        Path,
        typer.Argument(help="Measured trace (Parquet, the trace columns of docs/reference.md)."),
    ],
    scenario: ScenarioOption = None,
    output: OutputDir = None,
    actuator: Annotated[
        str | None,
        typer.Option(
            "--actuator", help="Actuator the trace was recorded on (for `emaprog trend`)."
        ),
    ] = None,
    usage: Annotated[
        float | None,
        typer.Option(
            "--usage",
            min=0.0,
            help="Its usage at the recording [flight hours] (for `emaprog trend`).",
        ),
    ] = None,
    parameters: ParametersOverride = None,
    columns: ColumnsOption = None,
    nuisances: Annotated[
        str | None,
        typer.Option(
            "--nuisances",
            help="Operating conditions to estimate beside the faults: a comma list "
            "of hinge_moment, resistance_factor, hinge_stiffness, or none. Default: the first "
            "two for a real unit (a rig recording or a commissioned unit's set), none for a "
            "twin experiment.",
        ),
    ] = None,
    force: ForceOption = False,
):
    """Identify fault magnitudes in a measured trace with the GA over the Monitor Model."""
    from . import api

    _say_if_compiling()

    if (actuator is None) != (usage is None):
        raise InputError(
            "--actuator/--usage",
            "give both (an inspection of one actuator at one usage) or neither",
        )
    inspection = {"actuator": actuator, "usage": usage} if actuator is not None else None
    report = api.identify(
        trace,
        scenario=scenario,
        parameters=parameters,
        columns=columns,
        output=output or Path("out") / f"{trace.stem}-report",
        inspection=inspection,
        nuisances=_nuisance_list(nuisances),
        force=force,
        show_progress=True,
    )
    typer.echo(api.verdict_text(report))
    typer.echo(f"report: {Path(report.folder or '.') / 'report.md'}")


def _nuisance_list(text: str | None) -> list[str] | None:
    """``--nuisances`` as a list (None: not given)."""
    from .identification.objective import NUISANCE_DEFAULTS

    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if names == ["none"]:
        return []
    unknown = [n for n in names if n not in NUISANCE_DEFAULTS]
    if unknown or not names:
        raise InputError(
            "--nuisances",
            f"unknown operating condition '{(unknown or [text])[0]}' "
            f"(allowed: a comma list of {', '.join(NUISANCE_DEFAULTS)}, or none)",
        )
    return list(dict.fromkeys(names))


@app.command(epilog="Example: emaprog calibrate -o out/calibration")
@guarded
def calibrate(parameters: ParametersOption = "default", output: OutputDir = None):
    """Fit the Monitor Model's equivalents and eccentricity gain to the Reference Model.

    Writes calibration.json, a figure and the calibrated parameter set (parameters.yaml)
    into the output folder; the input set is never modified.
    """
    from . import api

    result = api.calibrate(parameters, output or Path("out") / "calibration")
    typer.echo(
        f"eccentricity_gain c = {result.eccentricity_gain:.4f} "
        f"(r^2 = {result.r_squared:.4f}); commutation_loss = "
        f"{result.commutation_loss:.3e} s/rad"
    )
    errors = ", ".join(f"{k} {v:.2f}" for k, v in result.signature_error.items())
    typer.echo(f"signature errors: {errors}")
    typer.echo(
        f"calibration: {result.folder / 'calibration.json'}; calibrated set: {result.parameter_set}"
    )


@app.command(epilog="Example: emaprog trend configs/history-demo.yaml --simulate -o out/demo-trend")
@guarded
def trend(
    history: Annotated[
        Path,
        typer.Argument(
            help="Parquet history table, folder of report.json, or (with --simulate) a history YAML."
        ),
    ],
    output: OutputDir = None,
    simulate: Annotated[
        bool,
        typer.Option(
            "--simulate", help="Simulate and identify the inspections of a synthetic history YAML."
        ),
    ] = False,
    law: Annotated[str, typer.Option("--law", help="auto | linear | exponential")] = "auto",
    parameters: Annotated[
        str,
        typer.Option(
            "--parameters", "-p", help="Parameter set of the thresholds (tables and reports)."
        ),
    ] = "default",
    workers: Annotated[
        int | None,
        typer.Option(
            "--workers",
            "-w",
            min=1,
            help="Local worker processes for --simulate (default: all cores).",
        ),
    ] = None,
    resume: Annotated[
        bool, typer.Option("--resume", help="Keep inspections already identified.")
    ] = False,
):
    """Fit fault growth over usage and predict the remaining useful life (prognosis)."""
    from . import api

    result = api.trend(
        history,
        output,
        simulate=simulate,
        law=law,
        parameters=parameters,
        workers=workers,
        resume=resume,
        show_progress=True,
    )
    for fault, entry in result.faults.items():
        rul = entry["rul"]
        text = (
            entry["status"]
            if entry["status"] in ("not detected", "insufficient history")
            else "beyond horizon"
            if rul["median"] is None
            else f"{rul['median']:.0f} h (90 %: {rul['low']:.0f} - "
            + ("beyond horizon" if rul["high"] is None else f"{rul['high']:.0f} h")
            + ")"
        )
        typer.echo(f"{fault:14s} {entry['law'] or '-':11s} RUL {text}")
    typer.echo(f"trend: {result.folder / 'trend.md'}")


@app.command(epilog="Example: emaprog sweep campaigns/quick.yaml -o out/quick --workers 2")
@guarded
def sweep(
    campaign: Annotated[Path, typer.Argument(help="Campaign YAML.")],
    output: OutputDir = None,
    workers: Annotated[
        int | None,
        typer.Option("--workers", "-w", min=1, help="Local worker processes (default: all cores)."),
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option("--scheduler", help="Address of a Dask distributed scheduler.")
    ] = None,
    resume: Annotated[bool, typer.Option("--resume", help="Skip finished cases.")] = False,
    baseline: Annotated[
        Path | None,
        typer.Option("--baseline", help="summary.json to compare with; exit 3 if worse."),
    ] = None,
):
    """Run a Monte-Carlo campaign of simulate + identify cases (resumable)."""
    from . import api

    outcome = api.sweep(
        campaign,
        output,
        workers=workers,
        scheduler=scheduler,
        resume=resume,
        baseline=baseline,
        show_progress=True,
    )
    s = outcome.summary
    typer.echo(
        f"cases: {s['finished']} of {s['planned']} finished ({outcome.ran} run now, "
        f"{outcome.skipped} from earlier runs), {outcome.failed} failed"
    )
    fa = s["false_alarms"]
    detection = ", ".join(
        f"{f} {d['rate']:.0%}" for f, d in s["detection"].items() if d["rate"] is not None
    )
    typer.echo(
        f"detection: {detection or 'no faulty case'}; false alarms on healthy cases: "
        f"{fa['flagged']} of {fa['healthy_cases']}"
    )
    typer.echo(f"summary: {outcome.folder / 'summary.md'}")
    if outcome.regressions:
        typer.echo(f"emaprog: regressed against {baseline}:", err=True)
        for line in outcome.regressions:
            typer.echo(f"  {line}", err=True)
        raise typer.Exit(EXIT_REGRESSED)
    if baseline is not None:
        typer.echo(f"baseline {baseline}: no figure worse than its tolerance")
