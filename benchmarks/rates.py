"""Identification accuracy against the recording's sample rate, on the 10 regression cases.

Each case of ``campaigns/regression.yaml`` (random combinations of the four faults,
noisy Reference traces at the 10 kHz controller rate) is identified from the same
recording logged at 10, 5, 2 and 1 kHz (every 1st, 2nd, 5th, 10th row), at 20 kHz
(the 10 kHz trace interpolated linearly: our Reference writes at its controller
rate, so this row checks the faster-than-controller path, not extra information),
and at 5 kHz with the equivalent current rebuilt from the phase currents (what a
logger without an equivalent-current channel gives). Table: share of cases within
the tolerance per quantity, p95 errors, median time per identification.
Run: ``python benchmarks/rates.py [--json]`` (2 processes, about 5 minutes on 2 cores).
"""

from __future__ import annotations

import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from _output import finish, parser  # the sibling module benchmarks/_output.py

ROOT = Path(__file__).resolve().parent.parent
CAMPAIGN = ROOT / "campaigns" / "regression.yaml"
VARIANTS = (
    "20 kHz (interpolated)",
    "10 kHz",
    "5 kHz",
    "2 kHz",
    "1 kHz",
    "5 kHz, current from phases",
)
TOLERANCE = {"friction": 0.05, "backlash": 5e-5, "short_circuit": 0.03, "zeta": 0.05}


def _logged(columns: dict[str, np.ndarray], variant: str) -> dict[str, np.ndarray]:
    if variant.startswith("20 kHz"):
        t = columns["time"]
        fine = np.arange(2 * t.size - 1) / 2e4
        return {k: np.interp(fine, t, v) for k, v in columns.items()}
    step = {"10 kHz": 1, "5 kHz": 2, "2 kHz": 5, "1 kHz": 10}[variant.split(",")[0]]
    logged = {k: v[::step].copy() for k, v in columns.items()}
    if "from phases" in variant:
        from emaprog.config import parameters
        from emaprog.io.recordings import current_demand

        magnitude = 0.5 * sum(np.abs(logged[f"current_{x}"]) for x in "abc")
        sign = np.sign(
            current_demand(
                logged["time"],
                logged["command"],
                logged["position"],
                logged["speed"],
                parameters.load("default"),
            )
        )
        logged["current"] = magnitude * sign
    return logged


def run_case(case_id: int) -> list[dict]:
    import numba

    numba.set_num_threads(1)
    import pandas as pd

    import emaprog
    from emaprog.campaign import cases
    from emaprog.config.scenario import load_campaign
    from emaprog.models import reference

    campaign, base = load_campaign(CAMPAIGN)
    params = cases.load_parameters(CAMPAIGN, campaign, base)
    spec = next(cases.case_specs(campaign, base, params, "rates", [case_id]))
    trace = reference.simulate(spec.scenario, params)
    rows = []
    for variant in VARIANTS:
        frame = pd.DataFrame(_logged(trace.columns, variant))
        frame.attrs["emaprog"] = trace.metadata  # the case's scenario: its settings and truth
        report = emaprog.identify(frame)
        rows.append(
            {
                "case": case_id,
                "variant": variant,
                "error": report.error,
                "elapsed_s": report.elapsed_s,
                "true_friction": report.truth["friction"],
            }
        )
    return rows


def summarize(rows: list[dict]) -> list[dict]:
    out = []
    for variant in VARIANTS:
        mine = [r for r in rows if r["variant"] == variant]
        friction = np.array([abs(r["error"]["friction"]) / r["true_friction"] for r in mine])
        backlash = np.array([abs(r["error"]["backlash"]) for r in mine])
        short = np.array([max(abs(v) for v in r["error"]["short_circuit"].values()) for r in mine])
        zeta = np.array([abs(r["error"]["eccentricity"]["zeta"]) for r in mine])
        out.append(
            {
                "variant": variant,
                "friction_within": float(np.mean(friction <= TOLERANCE["friction"])),
                "backlash_within": float(np.mean(backlash <= TOLERANCE["backlash"])),
                "short_circuit_within": float(np.mean(short <= TOLERANCE["short_circuit"])),
                "zeta_within": float(np.mean(zeta <= TOLERANCE["zeta"])),
                "friction_p95": float(np.percentile(friction, 95)),
                "backlash_p95": float(np.percentile(backlash, 95)),
                "short_circuit_p95": float(np.percentile(short, 95)),
                "zeta_p95": float(np.percentile(zeta, 95)),
                "identify_s": float(np.median([r["elapsed_s"] for r in mine])),
            }
        )
    return out


def table(summary: list[dict]) -> str:
    lines = [
        "| recording | friction | backlash | PSC (worst phase) | zeta | friction p95 (rel.) | "
        "backlash p95 [rad] | PSC p95 | zeta p95 | identify [s] |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s in summary:
        lines.append(
            f"| {s['variant']} | {s['friction_within']:.0%} | {s['backlash_within']:.0%} | "
            f"{s['short_circuit_within']:.0%} | {s['zeta_within']:.0%} | "
            f"{s['friction_p95']:.3f} | {s['backlash_p95']:.1e} | "
            f"{s['short_circuit_p95']:.3f} | {s['zeta_p95']:.3f} | {s['identify_s']:.1f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = parser(__doc__).parse_args(argv)
    import multiprocessing

    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        rows = [row for case in pool.map(run_case, range(10)) for row in case]
    return finish(summarize(rows), table, args.json)


if __name__ == "__main__":
    sys.exit(main())
