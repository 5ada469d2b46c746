"""Calibrate the intervals' model-error factors on finished campaigns.

Each case row of a sweep carries, per quantity, the estimate, the truth and the
standard error ``se`` the interval was built from (the model-error factor in it),
and ``twin``: whether the twin experiment's factors were used
(:func:`emaprog.identification.confidence.is_twin`) or a unit's. The multiplier of
that standard error that the case needed for its 90 % interval to hold the truth is
``|error| / (1.645 se)`` (the eccentricity phase: its angular error on the circle,
counted where the true zeta reaches the incipient threshold, as the campaign
summary does). Per basis (twin, unit), the factor that gives 90 % coverage on the
pooled rows of that basis is today's factor times the 90th percentile of those
multipliers. The table gives, per basis and quantity, the coverage at today's
factors, the proposed factor, and the coverage it would give on each campaign with
a 90 % Wilson interval (with 50 cases a perfectly calibrated interval still lands
outside 85-95 % about one time in four). Run it on campaigns made with the factors
in the code: it scales those.

Run: ``python benchmarks/interval_factors.py RESULTS_DIR [RESULTS_DIR ...] [--json]``.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from emaprog.config import parameters
from emaprog.faults import CATALOGUE, QUANTITIES
from emaprog.identification.confidence import Z90, quantity_factor

from _output import finish, parser  # the sibling module benchmarks/_output.py

TARGET = 0.90


def wilson(hits: int, n: int, z: float = Z90) -> tuple[float, float]:
    """Wilson score interval of a binomial share (90 % with the default z)."""
    if n == 0:
        return math.nan, math.nan
    p = hits / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def multipliers(frame: pd.DataFrame, name: str, incipient: dict[str, float]) -> np.ndarray:
    """Per case, the multiple of its standard error its 90 % interval needed."""
    q = QUANTITIES[name]
    est = frame[f"est_{name}"].to_numpy(float)
    true = frame[f"true_{name}"].to_numpy(float)
    se = frame[f"se_{name}"].to_numpy(float)
    if q.circular:
        fault = next(f for f in CATALOGUE if name in {x.name for x in f.quantities})
        severity = np.max([np.abs(frame[f"true_{m.name}"].to_numpy(float) - m.healthy)
                           for m in fault.magnitudes], axis=0)
        keep = severity >= incipient[fault.name]
        error = np.abs(np.remainder(true - est + math.pi, 2.0 * math.pi) - math.pi)
    else:
        keep = np.ones(len(frame), bool)
        error = np.abs(true - est)
    with np.errstate(divide="ignore", invalid="ignore"):
        need = np.where(np.isfinite(se) & (se > 0), error / (Z90 * se), 0.0)
    need = np.where(np.isfinite(se) & (se == 0) & (error > 0), np.inf, need)
    return need[keep]


def load(directory: Path) -> pd.DataFrame:
    files = sorted((directory / "cases").glob("case-*.parquet"))
    if not files:
        raise SystemExit(f"{directory}: no case rows under cases/")
    return pd.concat([pd.read_parquet(f) for f in files], ignore_index=True)


def calibrate(directories: list[Path]) -> list[dict]:
    health = parameters.load("default").spec.health
    incipient = {f.name: getattr(health, f.name).incipient for f in CATALOGUE}
    frames = {str(d): load(d) for d in directories}
    rows = []
    for twin in (True, False):
        chosen = {d: f[f["twin"] == twin] for d, f in frames.items()}
        chosen = {d: f for d, f in chosen.items() if len(f)}
        if chosen:
            rows += _basis(chosen, twin, incipient)
    return rows


def _basis(frames: dict[str, pd.DataFrame], twin: bool, incipient: dict) -> list[dict]:
    rows = []
    for name in QUANTITIES:
        needs = {d: multipliers(f, name, incipient) for d, f in frames.items()}
        pooled = np.concatenate(list(needs.values()))
        scale = float(np.quantile(pooled, TARGET)) if pooled.size else math.nan
        factor = quantity_factor(name, twin)
        row = {"basis": "twin" if twin else "unit", "quantity": name, "factor": factor,
               "proposed": factor * scale, "campaigns": {}}
        for d, need in needs.items():
            hits_now, hits_new = int((need <= 1.0).sum()), int((need <= scale).sum())
            row["campaigns"][d] = {"n": int(need.size), "coverage": hits_now / max(need.size, 1),
                                   "proposed_coverage": hits_new / max(need.size, 1),
                                   "proposed_wilson90": wilson(hits_new, need.size)}
        rows.append(row)
    return rows


def table(rows: list[dict]) -> str:
    lines = ["| basis | quantity | factor | coverage now | proposed factor | coverage with it "
             "(90 % Wilson) |", "|---|---|---|---|---|---|"]
    for r in rows:
        now = ", ".join(f"{Path(d).name} {c['coverage']:.0%}" for d, c in r["campaigns"].items())
        new = ", ".join(f"{Path(d).name} {c['proposed_coverage']:.0%} "
                        f"({c['proposed_wilson90'][0]:.0%}-{c['proposed_wilson90'][1]:.0%}, "
                        f"n {c['n']})" for d, c in r["campaigns"].items())
        lines.append(f"| {r['basis']} | {r['quantity']} | {r['factor']:g} | {now} | "
                     f"{r['proposed']:.2f} | {new} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    cli = parser(__doc__)
    cli.add_argument("results", nargs="+", type=Path, help="sweep results directories")
    args = cli.parse_args(argv)
    return finish(calibrate(args.results), table, args.json)


if __name__ == "__main__":
    sys.exit(main())
