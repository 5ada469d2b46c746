"""Twin experiments on the shipped configs: simulate (Reference, noisy) -> identify -> table.

Writes ``docs/validation.md`` and the figures of each case under ``docs/validation/``.
Run: ``python benchmarks/validation.py`` (about a minute on 2 cores).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from emaprog import api
from emaprog.report import ROWS, _fmt, _pick

ROOT = Path(__file__).resolve().parent.parent
CASES = (
    "chirp-nominal",
    "friction",
    "backlash",
    "short-circuit",
    "eccentricity",
    "fig10-multiple-faults",
)


def main(out: Path = ROOT / "docs") -> list[dict]:
    results = []
    for name in CASES:
        trace = out / "validation" / f"{name}.parquet"
        api.simulate(ROOT / "configs" / f"{name}.yaml", output=trace)
        report = api.identify(trace, output=out / "validation" / name, force=True)
        trace.unlink()
        results.append({"case": name, **report.data})
    lines = [
        "# Identification on the shipped configs (twin experiments)",
        "",
        "Reference Model traces with sensor noise, identified with the default settings",
        "(population 32, 20 generations, least-squares polish, nominal-discrepancy",
        "correction), with each estimate's 90 % interval.",
        "Regenerate with `python benchmarks/validation.py`.",
        "",
    ]
    for r in results:
        lines += [
            f"## {r['case']}",
            "",
            f"health: {', '.join(f'{k} {v}' for k, v in r['health'].items())}; "
            f"{r['evaluations']} Monitor runs, {r['elapsed_s']:.1f} s",
            "",
            "| quantity | truth | estimate | 90 % interval | error |",
            "|---|---|---|---|---|",
        ]
        for label, keys, unit, fmt in ROWS:
            interval = _pick(r["interval"], keys)
            shown = (
                "—"
                if interval is None
                else f"[{fmt.format(interval[0])}, {fmt.format(interval[1])}]"
            )
            lines.append(
                f"| {label} [{unit}] | {_fmt(_pick(r['truth'], keys), fmt)} | "
                f"{_fmt(_pick(r['estimate'], keys), fmt)} | {shown} | "
                f"{_fmt(_pick(r['error'], keys), fmt)} |"
            )
        lines += ["", f"![fit](validation/{r['case']}/fit.png)", ""]
    (out / "validation.md").write_text("\n".join(lines))
    return results


if __name__ == "__main__":
    for r in main():
        print(
            json.dumps(
                {
                    "case": r["case"],
                    "error": r["error"],
                    "health": r["health"],
                    "elapsed_s": round(r["elapsed_s"], 2),
                }
            ),
            file=sys.stdout,
        )
