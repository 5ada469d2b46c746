"""Accuracy against time of the GA settings: the regression campaign under several populations.

For each (population, generations) the 10 cases of ``campaigns/regression.yaml``
(random combinations of the four faults on noisy Reference traces) are
identified; the table gives the share of cases within tolerance per
fault, the worst-phase short-circuit and zeta p95 errors, and the median
identification time per case (2 workers on 2 cores).
Run: ``python benchmarks/ga_tradeoff.py [--json]``; the last line with ``--json``
is one JSON list.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import yaml
from _output import finish, parser  # the sibling module benchmarks/_output.py

from emaprog import api

ROOT = Path(__file__).resolve().parent.parent
CAMPAIGN = ROOT / "campaigns" / "regression.yaml"
SETTINGS = ((16, 20), (32, 20), (32, 40), (64, 20), (64, 40), (128, 40))


def run(population: int, generations: int) -> dict:
    data = yaml.safe_load(CAMPAIGN.read_text())
    data["scenario"] = str((CAMPAIGN.parent / data["scenario"]).resolve())
    data["identify"] = {"ga": {"population": population, "generations": generations}}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "campaign.yaml"
        path.write_text(yaml.safe_dump(data))
        summary = api.sweep(path, Path(tmp) / "results", show_progress=False).summary
    errors = summary["errors"]
    phases = [errors[f"short_circuit_{x}"] for x in "abc"]
    return {
        "population": population,
        "generations": generations,
        "friction_within": errors["friction"]["within_tolerance"],
        "backlash_within": errors["backlash"]["within_tolerance"],
        "short_circuit_within": min(p["within_tolerance"] for p in phases),
        "zeta_within": errors["eccentricity_zeta"]["within_tolerance"],
        "short_circuit_p95": max(p["p95"] for p in phases),
        "zeta_p95": errors["eccentricity_zeta"]["p95"],
        "identify_s": summary["timing"]["median_identify_s"],
    }


def table(rows: list[dict]) -> str:
    head = (
        "| population x generations | friction | backlash | PSC (worst phase) | zeta | "
        "PSC p95 | zeta p95 | identify [s] |"
    )
    lines = [head, "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['population']} x {r['generations']} | {r['friction_within']:.0%} | "
            f"{r['backlash_within']:.0%} | {r['short_circuit_within']:.0%} | "
            f"{r['zeta_within']:.0%} | {r['short_circuit_p95']:.3f} | "
            f"{r['zeta_p95']:.3f} | {r['identify_s']:.1f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = parser(__doc__).parse_args(argv)
    return finish([run(p, g) for p, g in SETTINGS], table, args.json)


if __name__ == "__main__":
    sys.exit(main())
