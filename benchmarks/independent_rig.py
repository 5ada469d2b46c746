"""The documented rig workflow on units of an independently written simulator.

Each unit (``independent_unit.spread_unit``: build tolerances, logger gains and offsets, a
random rotor electrical zero) is written as a rig folder by :mod:`independent_unit`: two
healthy recordings (20 N m under a 1500 N m/rad spring, 45 N m without), then inspections
under 30 N m and 2000 N m/rad, each unit held under its load before its logger starts.
The README's commands run on them exactly as a user types them (``emaprog commission ...
-p default-pwm``, ``emaprog identify ... -p UNIT.yaml``, no other option), and each report
is compared with the simulator's truth: the verdicts (nominal / incipient / degraded /
inconclusive) against the fault's true severity, the estimates against the accuracy
tolerances of docs/reference.md (Faults), the named phase against the shorted winding's
logger channel.

``--set fig10-parts`` inspects instead the Fig. 10 set, the set without each of its four
faults, and each fault alone at its Fig. 10 magnitude (nine inspections a unit): which
fault, beside which others, the Monitor meets least on a unit of this form. ``--ideal
cogging,hall`` makes those differences of form ideal (``independent_unit.IDEALS``: cogging,
hall, stribeck, warming, emf-edges, dead-time, logger-gains), to measure what each costs.

``--motor-angle`` has the logger record the drive's resolver angle too (16 bits within a
turn), mapped as ``motor_angle``.

Run: ``python benchmarks/independent_rig.py OUT_DIR [--units N] [--seed S]
[--set standard|fig10-parts] [--ideal NAMES] [--motor-angle] [--json]`` (about 1.5 min a unit on 2 cores;
fig10-parts about 10 min).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import independent_unit as iu  # noqa: E402
from _output import finish, parser  # noqa: E402

#: Incipient thresholds of ``default-pwm`` (its ``health``) and the accuracy tolerances of
#: the fault catalogue (docs/reference.md, Faults), written out: this script reads reports
#: as a user would, not emaprog's tables.
INCIPIENT = {"friction": 0.15, "backlash": 1e-4, "short_circuit": 0.05, "eccentricity": 0.08}
DEGRADED = {"friction": 0.6, "backlash": 5e-4, "short_circuit": 0.2, "eccentricity": 0.3}
TOLERANCE = {"friction": 0.05, "backlash": 5e-5, "short_circuit": 0.03, "eccentricity": 0.05}
#: The inspections every unit gets: (file, faults).
INSPECTIONS = {
    "healthy.csv": iu.Faults(),
    "friction.csv": iu.Faults(friction=1.4),
    "backlash.csv": iu.Faults(backlash=3e-4),
    "short.csv": iu.Faults(short_circuit=(0.0, 0.15, 0.0)),
    "eccentricity.csv": iu.Faults(zeta=0.25, phi=1.0),
    "fig10.csv": iu.Faults(1.8, 4e-4, (0.2, 0.0, 0.0), 0.2, 0.0),
}
#: The Fig. 10 set taken apart: the set, the set without each fault, each fault alone
#: (a fault's fields, absent as ``Faults()`` has them).
FIG10 = INSPECTIONS["fig10.csv"]
_FIELDS = {
    "friction": ("friction",),
    "backlash": ("backlash",),
    "short": ("short_circuit",),
    "eccentricity": ("zeta", "phi"),
}


def _taken(faults: iu.Faults, source: iu.Faults, fields: tuple[str, ...]) -> iu.Faults:
    return replace(faults, **{k: getattr(source, k) for k in fields})


FIG10_PARTS = {
    "fig10.csv": FIG10,
    **{f"fig10-no-{f}.csv": _taken(FIG10, iu.Faults(), k) for f, k in _FIELDS.items()},
    **{f"{f}-alone.csv": _taken(iu.Faults(), FIG10, k) for f, k in _FIELDS.items()},
}
SETS = {"standard": INSPECTIONS, "fig10-parts": FIG10_PARTS}
LOGGER_CHANNELS = ("I_U [A]", "I_V [A]", "I_W [A]")


def severities(faults: iu.Faults) -> dict[str, float]:
    return {
        "friction": abs(faults.friction - 1.0),
        "backlash": faults.backlash,
        "short_circuit": max(faults.short_circuit),
        "eccentricity": faults.zeta,
    }


def true_verdict(fault: str, severity: float) -> str:
    if severity >= DEGRADED[fault]:
        return "degraded"
    return "incipient" if severity >= INCIPIENT[fault] else "nominal"


def run(cmd: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=False)


def unit_rows(
    folder: Path,
    seed: int,
    inspected: dict[str, iu.Faults] = INSPECTIONS,
    ideals: tuple[str, ...] = (),
    motor_angle: bool = False,
) -> list[dict]:
    """Write unit ``seed``'s folder (its differences ``ideals`` made ideal; with
    ``motor_angle`` its logger records the resolver angle), run the rig commands, compare
    each report with the truth."""
    unit = iu.ideal(iu.spread_unit(np.random.default_rng(seed)), ideals)
    healthy = [
        iu.Test(hinge_moment=20.0, spring=1500.0, seed=100 * seed + 1),
        iu.Test(hinge_moment=45.0, seed=100 * seed + 2),
    ]
    inspections = {
        name: (faults, iu.Test(hinge_moment=30.0, spring=2000.0, seed=100 * seed + 10 + j))
        for j, (name, faults) in enumerate(inspected.items())
    }
    iu.write_unit(folder, unit, healthy, inspections, motor_angle)
    commissioned = run(
        ["emaprog", "commission", "healthy-0.csv", "healthy-1.csv", "--columns", "logger.yaml"]
        + ["-o", "unit.yaml", "-p", "default-pwm"],
        folder,
    )
    if commissioned.returncode != 0:
        return [{"unit": seed, "recording": "commission", "refused": commissioned.stderr[-300:]}]
    rows = []
    for name, (faults, _) in inspections.items():
        report = folder / ("report-" + name.removesuffix(".csv"))
        done = run(
            ["emaprog", "identify", name, "--columns", "logger.yaml", "-p", "unit.yaml"]
            + ["-o", report.name],
            folder,
        )
        if done.returncode != 0:
            rows.append({"unit": seed, "recording": name, "refused": done.stderr[-300:]})
            continue
        rows.append(compare(json.loads((report / "report.json").read_text()), faults, seed, name))
    return rows


def compare(report: dict, faults: iu.Faults, seed: int, name: str) -> dict:
    """One inspection's report against its truth."""
    est = report["estimate"]
    sev = severities(faults)
    row: dict = {
        "unit": seed,
        "recording": name,
        "fit_ratio": report["confidence"]["noise_floor"]["ratio"],
    }
    estimates = {
        "friction": est["friction"] - faults.friction,
        "backlash": est["backlash"] - faults.backlash,
        "eccentricity": est["eccentricity"]["zeta"] - faults.zeta,
    }
    # the short circuit per logger channel: the report's windings named by their channels
    channels = report.get("phase_channels") or {w: w for w in "abc"}
    by_channel = {channels[w]: est["short_circuit"][w] for w in "abc"}
    truth_by_channel = dict(zip(LOGGER_CHANNELS, faults.short_circuit))
    estimates["short_circuit"] = max(
        abs(by_channel.get(c, 0.0) - truth_by_channel[c]) for c in LOGGER_CHANNELS
    )
    for fault, verdict in report["health"].items():
        truth = true_verdict(fault, sev[fault])
        row[f"{fault}_verdict"] = verdict
        row[f"{fault}_truth"] = truth
        row[f"{fault}_error"] = estimates[fault]
        row[f"{fault}_within"] = abs(estimates[fault]) <= TOLERANCE[fault] * (
            faults.friction if fault == "friction" else 1.0
        )
    named = report.get("short_circuit_phase")
    shorted = max(range(3), key=lambda j: faults.short_circuit[j])
    if sev["short_circuit"] >= INCIPIENT["short_circuit"]:
        row["phase_named"] = None if named is None else channels.get(named, named)
        row["phase_truth"] = LOGGER_CHANNELS[shorted]
    return row


def summarise(rows: list[dict]) -> dict:
    """Shares over the inspections: verdicts right, false alarms, inconclusive, within tolerance."""
    done = [r for r in rows if "refused" not in r]
    out: dict = {
        "inspections": len(done),
        "refused": len(rows) - len(done),
        "fit_ratio_median": float(sorted(r["fit_ratio"] for r in done)[len(done) // 2])
        if done
        else math.nan,
    }
    for fault in INCIPIENT:
        verdicts = [(r[f"{fault}_verdict"], r[f"{fault}_truth"]) for r in done]
        present = [v for v, t in verdicts if t != "nominal"]
        absent = [v for v, t in verdicts if t == "nominal"]
        out[fault] = {
            "present": len(present),
            "detected": sum(v in ("incipient", "degraded") for v in present),
            "inconclusive": sum(v == "inconclusive" for v, _ in verdicts),
            "false_alarms": sum(v in ("incipient", "degraded") for v in absent),
            "within": sum(bool(r[f"{fault}_within"]) for r in done),
        }
    named = [r for r in done if "phase_truth" in r]
    out["phase"] = {
        "shorts": len(named),
        "named_right": sum(r["phase_named"] == r["phase_truth"] for r in named),
        "named_wrong": sum(r["phase_named"] not in (None, r["phase_truth"]) for r in named),
    }
    return out


def table(result: dict) -> str:
    s = result["summary"]
    lines = [
        f"independent units: {result['units']}, inspections {s['inspections']} "
        f"(refused {s['refused']}), fit / floor median {s['fit_ratio_median']:.1f}",
        "| fault | present | detected | false alarms | inconclusive | within tolerance |",
        "|---|---|---|---|---|---|",
    ]
    for fault in INCIPIENT:
        f = s[fault]
        lines.append(
            f"| {fault} | {f['present']} | {f['detected']} | {f['false_alarms']} | "
            f"{f['inconclusive']} | {f['within']} of {s['inspections']} |"
        )
    p = s["phase"]
    lines.append(
        f"shorted phase named right in {p['named_right']} of {p['shorts']}, wrong in "
        f"{p['named_wrong']}"
    )
    for r in result["rows"]:
        if "refused" in r:
            lines.append(f"unit {r['unit']} {r['recording']}: refused: {r['refused']}")
            continue
        verdicts = ", ".join(
            f"{f} {r[f + '_verdict']} ({r[f + '_truth']}, err {r[f + '_error']:.3g})"
            for f in INCIPIENT
        )
        lines.append(f"unit {r['unit']} {r['recording']}: fit {r['fit_ratio']:.1f} x; {verdicts}")
    return "\n".join(lines)


def ideal_names(text: str) -> tuple[str, ...]:
    """``--ideal``'s comma list, each a key of ``independent_unit.IDEALS``."""
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    unknown = [n for n in names if n not in iu.IDEALS]
    if unknown:
        raise argparse.ArgumentTypeError(
            f"unknown difference(s) {', '.join(unknown)}; allowed: {', '.join(iu.IDEALS)}"
        )
    return names


def main() -> int:
    args = parser(__doc__)
    args.add_argument("out", type=Path)
    args.add_argument("--units", type=int, default=4)
    args.add_argument("--seed", type=int, default=1)
    args.add_argument("--set", choices=sorted(SETS), default="standard", dest="inspections")
    args.add_argument("--ideal", type=ideal_names, default=(), help="e.g. cogging,hall")
    args.add_argument(
        "--motor-angle", action="store_true", help="the logger records the resolver angle too"
    )
    a = args.parse_args()
    rows: list[dict] = []
    for seed in range(a.seed, a.seed + a.units):
        folder = a.out / f"unit-{seed}"
        rows += unit_rows(folder, seed, SETS[a.inspections], a.ideal, a.motor_angle)
    result = {
        "units": a.units,
        "seed": a.seed,
        "set": a.inspections,
        "ideal": list(a.ideal),
        "motor_angle": a.motor_angle,
        "summary": summarise(rows),
        "rows": rows,
    }
    return finish(result, table, a.json)


if __name__ == "__main__":
    raise SystemExit(main())
