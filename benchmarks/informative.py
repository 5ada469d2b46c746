"""Which recordings can support a verdict: identification on recordings at the edges.

The Fig. 10 unit (friction 1.8, backlash 4e-4 rad, 20 % short on A, zeta 0.2) and the
healthy unit, on the shipped set (twins: exact parameters), recorded with the standard
chirp cut to 0.05-0.5 s, with its amplitude shrunk to 0.005 and 0.0005 rad and to rest
(0), and with the sensor noise times 1, 5 and 20. Per recording: the gate's verdict
(``emaprog.identification.confidence.uninformative``: too short, not excited, mostly
noise), the fit ratio, and for the recordings the gate lets through whether every
quantity is within tolerance or its 90 % interval (an earned verdict) and
whether a fault is flagged that is absent (a false alarm).

Run: ``python benchmarks/informative.py [--json]`` (about 2 minutes on 2 cores).
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _output import finish, parser  # noqa: E402

import emaprog  # noqa: E402
from emaprog.config import parameters  # noqa: E402
from emaprog.config.parameters import ParameterFile, derive  # noqa: E402
from emaprog.faults import flatten, severity  # noqa: E402
from emaprog.io.storage import frame_of  # noqa: E402
from emaprog.models import reference  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
TOLERANCE = {
    "friction": 0.05,
    "backlash": 5e-5,
    "short_circuit_a": 0.03,
    "short_circuit_b": 0.03,
    "short_circuit_c": 0.03,
    "eccentricity_zeta": 0.05,
}


def noisy_set(factor: float):
    spec = parameters.load("default").spec.model_dump(mode="json")
    for key in ("position_noise", "speed_noise", "current_noise"):
        spec["sensors"][key] *= factor
    return derive(ParameterFile.model_validate(spec), f"default, noise x{factor:g}")


def one(faulty: bool, duration: float, amplitude: float, noise: float) -> dict:
    base = emaprog.load_scenario(ROOT / "configs" / "fig10-multiple-faults.yaml")
    data = base.model_dump(mode="json")
    data.update(duration=duration, name="edge")
    data["command"] = (
        {**data["command"], "amplitude": amplitude}
        if amplitude > 0
        else {"kind": "constant", "offset": 0.0}
    )
    if not faulty:
        data["faults"] = {}
    scenario = base.model_validate(data)
    params = noisy_set(noise)
    # the noisier rig's trace, identified with the shipped set (the Monitor has no noise)
    report = emaprog.identify(frame_of(reference.simulate(scenario, params)))
    why = report.data["confidence"]["inconclusive"]
    gated = any(
        ("too short" in w or "does not excite" in w or "mostly noise" in w) for w in why.values()
    )
    truth = flatten(scenario.faults)
    est = {
        "friction": report.estimate["friction"],
        "backlash": report.estimate["backlash"],
        "eccentricity_zeta": report.estimate["eccentricity"]["zeta"],
        **{f"short_circuit_{p}": v for p, v in report.estimate["short_circuit"].items()},
    }

    def error(q: str) -> float:
        return abs(est[q] / truth[q] - 1.0) if q == "friction" else abs(est[q] - truth[q])

    within = all(error(q) <= t for q, t in TOLERANCE.items())
    limits = params.spec.health
    false_alarm = any(
        report.health.get(f) in ("incipient", "degraded")
        and severity(f, truth) < getattr(limits, f).incipient
        for f in report.health
    )
    return {
        "faulty": faulty,
        "duration": duration,
        "amplitude": amplitude,
        "noise": noise,
        "gated": gated,
        "inconclusive": sorted(why),
        "ratio": report.data["confidence"]["noise_floor"]["ratio"],
        "floor": report.data["confidence"]["noise_floor"]["fitness"],
        "within": bool(within),
        "false_alarm": bool(false_alarm),
    }


def table(result: list[dict]) -> str:
    lines = [
        "| unit | duration [s] | amplitude [rad] | noise | gate | ratio | floor | within tolerance | false alarm |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in result:
        lines.append(
            f"| {'Fig. 10' if r['faulty'] else 'healthy'} | {r['duration']:g} | "
            f"{r['amplitude']:g} | x{r['noise']:g} | {'inconclusive' if r['gated'] else 'pass'} | "
            f"{r['ratio']:.3g} | {r['floor']:.2g} | {'yes' if r['within'] else 'no'} | "
            f"{'YES' if r['false_alarm'] else 'no'} |"
        )
    return "\n".join(lines)


def main() -> int:
    ns = parser(__doc__).parse_args()
    cases = [(f, d, 0.05, 1.0) for f in (True, False) for d in (0.05, 0.1, 0.15, 0.2, 0.3, 0.5)]
    cases += [(f, 0.5, a, 1.0) for f in (True, False) for a in (0.005, 0.0005, 0.0)]
    cases += [(f, 0.5, 0.05, n) for f in (True, False) for n in (5.0, 20.0)]
    return finish([one(*c) for c in cases], table, ns.json)


if __name__ == "__main__":
    raise SystemExit(main())
