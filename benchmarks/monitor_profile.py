"""Where the Monitor step's time goes: the 0.5 s Fig. 10 chirp (20 000 steps) on one core,
with the model's parts switched on one at a time, beside the plain-loop yardstick.

Rows: the plain single-phase numba loop of ``benchmarks/run.py``; the healthy Monitor
without and with the commutation transients; then each fault alone (friction and
backlash; a 20 % short on phase A; eccentricity zeta 0.2, whose pair law costs a cos
and a sin a step); all Fig. 10 faults; the same commutating on a recorded motor angle
(docs/reference.md, "The models"). The differences between rows are what each
part costs a step. Each figure is the median of ``--repeat`` runs after a warm-up.
Run: ``python benchmarks/monitor_profile.py [--json] [--repeat N]``.
"""

from __future__ import annotations

import sys

import numba
import numpy as np
from _output import finish, parser  # the sibling module benchmarks/_output.py
from run import FIG10, median_time, plain_loop  # the sibling speed benchmark

from emaprog.config import parameters
from emaprog.config.scenario import load_scenario
from emaprog.faults import flatten, healthy_values, monitor_form
from emaprog.models import monitor
from emaprog.models.common import inputs
from emaprog.numerics import DEFAULT


def measure(repeat: int) -> list[dict]:
    scenario = load_scenario(FIG10)
    params = parameters.load("default")
    inp = inputs(scenario, params)
    gain = params.spec.monitor.eccentricity_gain
    healthy = healthy_values()
    steps = inp.command.size * DEFAULT.monitor_substeps
    options = monitor.options(params, DEFAULT)
    cases = {
        "healthy, no commutation transients": (healthy, options._replace(commutation=False)),
        "healthy": (healthy, options),
        "friction x1.8 and backlash 4e-4 rad": (
            {**healthy, "friction": 1.8, "backlash": 4e-4},
            options,
        ),
        "short circuit A 0.2": ({**healthy, "short_circuit_a": 0.2}, options),
        "eccentricity zeta 0.2": (
            {**healthy, "eccentricity_zeta": 0.2, "eccentricity_phase": 1.0},
            options,
        ),
        "Fig. 10 faults": (flatten(scenario.faults), options),
    }
    numba.set_num_threads(1)
    out = np.empty(inp.command.size)
    plain = median_time(
        lambda: plain_loop(inp.command, DEFAULT.monitor_substeps, out), max(repeat, 20)
    )
    rows = [{"case": "plain single-phase loop (yardstick)", "ms": 1e3 * plain}]
    for name, (values, opts) in cases.items():
        faults = monitor_form(values, gain)
        seconds = median_time(lambda f=faults, o=opts: monitor.run(params, inp, f, opts=o), repeat)
        rows.append({"case": name, "ms": 1e3 * seconds})
    # commutating on a recorded motor angle (a rig's resolver; here the Monitor's own travel)
    faults = monitor_form(flatten(scenario.faults), gain)
    recorded = inp._replace(motor_angle=monitor.run(params, inp, faults)["motor_angle"])
    seconds = median_time(lambda: monitor.run(params, recorded, faults), repeat)
    rows.append({"case": "Fig. 10 faults, on a recorded motor angle", "ms": 1e3 * seconds})
    for row in rows:
        row["ns_per_step"] = 1e6 * row["ms"] / steps
        row["per_plain"] = row["ms"] / rows[0]["ms"]
    return rows


def table(rows: list[dict]) -> str:
    lines = [
        "| run (0.5 s chirp, 20 000 steps, 1 core) | ms | ns a step | in plain loops |",
        "|---|---|---|---|",
    ]
    lines += [
        f"| {r['case']} | {r['ms']:.3f} | {r['ns_per_step']:.0f} | {r['per_plain']:.2f} |"
        for r in rows
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    cli = parser(__doc__)
    cli.add_argument("--repeat", type=int, default=40, help="runs per figure (median)")
    args = cli.parse_args(argv)
    return finish(measure(args.repeat), table, args.json)


if __name__ == "__main__":
    sys.exit(main())
