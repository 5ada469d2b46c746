"""Calibrate commissioning's standard errors on finished campaigns of commissioned units.

Each case row of a campaign with ``commission`` carries, per unit parameter, the
commissioning error (``commission_err_<p>``: commissioned / true - 1) and the fit's own
linearised relative standard error (``commission_se_<p>``, NaN where the parameter was held
at the base value), and the hinge moment's error and standard error [N m]. The linearised
error sees the noise, not the Monitor's deterministic mismatch with the unit, which
dominates (measured on the example rig unit: surface inertia +5 % at a standard error of
1.5 %, stiffness +6 % at 1.6 %). A model-error floor per parameter makes the reported
standard error ``sqrt(se^2 + floor^2)``; the floor is the smallest on a grid for which
``|error| <= 1.645 x`` that standard error in 90 % of the fitted units.

Run: ``python benchmarks/commission_errors.py CALIBRATION_DIR [--validate DIR ...] [--json]``
(after ``emaprog sweep campaigns/calibration-units.yaml -o CALIBRATION_DIR``).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _output import finish, parser  # noqa: E402

from emaprog.config.parameters import COMMISSIONED  # noqa: E402

Z90 = 1.6448536269514722
PARAMETERS = (*COMMISSIONED, "hinge_moment")


def pairs(frame: pd.DataFrame, name: str) -> tuple[np.ndarray, np.ndarray]:
    err = frame[f"commission_err_{name}"].to_numpy(float)
    se = frame[f"commission_se_{name}"].to_numpy(float)
    keep = np.isfinite(err) & np.isfinite(se)
    return np.abs(err[keep]), se[keep]


def coverage(err: np.ndarray, se: np.ndarray, floor: float) -> float:
    return float(np.mean(err <= Z90 * np.hypot(se, floor))) if err.size else math.nan


def calibrate(frame: pd.DataFrame) -> dict:
    out = {}
    for name in PARAMETERS:
        err, se = pairs(frame, name)
        if err.size < 20:
            continue
        top = 30.0 if name == "hinge_moment" else 0.3
        grid = np.linspace(0.0, top, 3001)
        floor = next((float(f) for f in grid if coverage(err, se, f) >= 0.90), top)
        out[name] = {
            "n": int(err.size),
            "coverage_linearised": coverage(err, se, 0.0),
            "floor": floor,
            "coverage": coverage(err, se, floor),
        }
    return out


def table(result: dict) -> str:
    lines = [
        "| parameter | n | coverage, linearised | floor | coverage | validation |",
        "|---|---|---|---|---|---|",
    ]
    for name, r in result["parameters"].items():
        val = ", ".join(f"{v[name]:.1%}" for v in result["validation"] if name in v)
        unit = " N m" if name == "hinge_moment" else ""
        lines.append(
            f"| {name} | {r['n']} | {r['coverage_linearised']:.1%} | "
            f"{r['floor']:.4g}{unit} | {r['coverage']:.1%} | {val or '—'} |"
        )
    return "\n".join(lines)


def main() -> int:
    args = parser(__doc__)
    args.add_argument("calibration", type=Path)
    args.add_argument("--validate", type=Path, nargs="*", default=[])
    ns = args.parse_args()
    frame = pd.read_parquet(ns.calibration / "cases")
    found = calibrate(frame)
    validation = []
    for folder in ns.validate:
        other = pd.read_parquet(folder / "cases")
        validation.append(
            {name: coverage(*pairs(other, name), r["floor"]) for name, r in found.items()}
        )
    return finish({"parameters": found, "validation": validation}, table, ns.json)


if __name__ == "__main__":
    raise SystemExit(main())
