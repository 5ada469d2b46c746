"""What a campaign's cases say together: error statistics, detection, false alarms, isolation.

Works on the case table of :class:`emaprog.campaign.cases.CaseStore` only (never
re-simulates). The tolerances are the accuracy tolerances (docs/reference.md, Faults).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import pandas as pd

from ..config.parameters import Parameters
from ..faults import CATALOGUE, FAULT_NAMES, NUISANCES, PHASE_FAULTS, PHASES, QUANTITIES
from ..identification.confidence import Z90
from ..identification.objective import NUISANCE_DEFAULTS

PHASE_NAMES = (*PHASES, "none")


class Accuracy(NamedTuple):
    """How a quantity's error is measured and the tolerance on it."""

    measure: str  # "absolute" | "relative" (error / true value)
    tolerance: float | None  # tolerance bar on |error| in that measure; None: no bar


#: Per quantity, from the fault catalogue.
ACCURACY = {name: Accuracy(q.measure, q.tolerance) for name, q in QUANTITIES.items()}

#: Regression tolerances of ``sweep --baseline``: a figure is "worse" only past these.
#: Error percentiles: 25 % relative growth plus a tenth of the tolerance, so float-level
#: differences between machines pass and a real loss of accuracy does not.
ERROR_GROWTH = 0.25
ERROR_FLOOR = 0.1
#: Rates (detection, isolation, false alarms): 0.1 absolute, about one case of a small
#: regression campaign's group.
RATE_SLACK = 0.10


def error_values(frame: pd.DataFrame, quantity: str, params: Parameters) -> np.ndarray:
    """Finite errors of one quantity in its ACCURACY measure (see :func:`summarize`).

    An angle counts only where its fault's true severity reaches the incipient
    threshold (below it the angle is not determined).
    """
    err = frame[f"err_{quantity}"].to_numpy(float)
    if ACCURACY[quantity].measure == "relative":
        err = err / frame[f"true_{quantity}"].to_numpy(float)
    if QUANTITIES[quantity].circular:
        fault = next(f for f in CATALOGUE if quantity in {q.name for q in f.quantities})
        true_severity = np.max(
            [np.abs(frame[f"true_{q.name}"].to_numpy(float) - q.healthy) for q in fault.magnitudes],
            axis=0,
        )  # faults.severity, per row
        err = err[true_severity >= getattr(params.spec.health, fault.name).incipient]
    return err[np.isfinite(err)]


def _statistics(err: np.ndarray, accuracy: Accuracy, unit: str) -> dict:
    size = int(err.size)
    if size == 0:
        return {
            "n": 0,
            "measure": accuracy.measure,
            "unit": unit,
            "tolerance": accuracy.tolerance,
            "bias": None,
            "mean": None,
            "median": None,
            "p95": None,
            "max": None,
            "within_tolerance": None,
        }
    magnitude = np.abs(err)
    within = None if accuracy.tolerance is None else float(np.mean(magnitude <= accuracy.tolerance))
    return {
        "n": size,
        "measure": accuracy.measure,
        "unit": "-" if accuracy.measure == "relative" else unit,
        "tolerance": accuracy.tolerance,
        "bias": float(np.mean(err)),
        "mean": float(np.mean(magnitude)),
        "median": float(np.median(magnitude)),
        "p95": float(np.percentile(magnitude, 95)),
        "max": float(np.max(magnitude)),
        "within_tolerance": within,
    }


def _rate(hits: int, total: int) -> float | None:
    return hits / total if total else None


def summarize(frame: pd.DataFrame, params: Parameters) -> dict:
    """Per-fault error statistics, detection and false-alarm rates, isolation confusion.

    * error statistics on |estimate - truth| (friction relative to its true value;
      the eccentricity phase only where the true zeta reaches the incipient
      threshold): mean, median, 95th percentile, max, share within tolerance;
    * detection rate per fault: among cases whose true severity reaches the
      fault's ``incipient`` threshold, the share whose verdict is not nominal;
    * false alarms: among the all-healthy cases, the share with any (and with
      each) fault not nominal; per fault also over all cases where that fault is
      truly below its incipient threshold;
    * isolation: true faulty phase (largest shorted fraction at or above the
      incipient threshold, else "none") against the phase the verdict named.
    """
    errors = {
        q: _statistics(error_values(frame, q, params), ACCURACY[q], QUANTITIES[q].unit)
        for q in QUANTITIES
    }
    detection, absent_alarms = {}, {}
    for fault in FAULT_NAMES:
        flagged = frame[f"health_{fault}"].isin(["incipient", "degraded"])
        present = frame[f"true_health_{fault}"] != "nominal"
        detection[fault] = {
            "cases": int(present.sum()),
            "detected": int((flagged & present).sum()),
            "rate": _rate(int((flagged & present).sum()), int(present.sum())),
        }
        absent_alarms[fault] = _rate(int((flagged & ~present).sum()), int((~present).sum()))
    healthy = frame[frame["healthy_case"]]
    flags = {f: healthy[f"health_{f}"].isin(["incipient", "degraded"]) for f in FAULT_NAMES}
    any_flag = np.logical_or.reduce([v.to_numpy() for v in flags.values()]) if len(healthy) else []
    false_alarms = {
        "healthy_cases": int(len(healthy)),
        "flagged": int(np.sum(any_flag)),
        "rate": _rate(int(np.sum(any_flag)), len(healthy)),
        "per_fault_on_healthy": {f: _rate(int(v.sum()), len(healthy)) for f, v in flags.items()},
        "per_fault_where_absent": absent_alarms,
    }
    return {
        "cases": int(len(frame)),
        "errors": errors,
        "intervals": _intervals(frame, params),
        "commissioning": _commissioning(frame),
        "nuisance": _nuisance(frame),
        "detection": detection,
        "false_alarms": false_alarms,
        "isolation": {fault: _isolation(frame, fault) for fault in PHASE_FAULTS},
        "timing": {
            "median_simulate_s": float(frame["simulate_s"].median()) if len(frame) else None,
            "median_identify_s": float(frame["identify_s"].median()) if len(frame) else None,
        },
    }


def _intervals(frame: pd.DataFrame, params: Parameters) -> dict | None:
    """Per quantity: how often the 90 % interval holds the truth, and its median width.

    Width in the quantity's ACCURACY measure (friction over its true value), set
    beside twice the tolerance; the phase's arc counts only where the true
    zeta reaches the incipient threshold (as its error does). Inconclusive
    verdicts are counted per fault.
    """
    if "low_friction" not in frame:
        return None
    out = {}
    for name, q in QUANTITIES.items():
        low = frame[f"low_{name}"].to_numpy(float)
        high = frame[f"high_{name}"].to_numpy(float)
        true = frame[f"true_{name}"].to_numpy(float)
        keep = np.isfinite(low) & np.isfinite(high)
        if q.circular:
            fault = next(f for f in CATALOGUE if name in {x.name for x in f.quantities})
            severity = np.max(
                [
                    np.abs(frame[f"true_{m.name}"].to_numpy(float) - m.healthy)
                    for m in fault.magnitudes
                ],
                axis=0,
            )
            keep &= severity >= getattr(params.spec.health, fault.name).incipient
            half = 0.5 * (high - low)
            centre = 0.5 * (high + low)
            offset = np.abs(np.remainder(true - centre + math.pi, 2.0 * math.pi) - math.pi)
            covered = (half >= math.pi) | (offset <= half + 1e-12)
            width = high - low
        else:
            covered = (true >= low - 1e-12) & (true <= high + 1e-12)
            width = high - low
            if q.measure == "relative":
                width = width / true
        n = int(keep.sum())
        bar = None if q.tolerance is None else 2.0 * q.tolerance
        out[name] = {
            "n": n,
            "coverage": _rate(int(covered[keep].sum()), n),
            "median_width": float(np.median(width[keep])) if n else None,
            "width_bar": bar,
        }
    inconclusive = {
        f: _rate(int((frame[f"health_{f}"] == "inconclusive").sum()), len(frame))
        for f in FAULT_NAMES
    }
    return {"quantities": out, "inconclusive": inconclusive}


def _spread(values: np.ndarray) -> dict:
    magnitude = np.abs(values[np.isfinite(values)])
    if not magnitude.size:
        return {"n": 0, "median": None, "p95": None, "max": None}
    return {
        "n": int(magnitude.size),
        "median": float(np.median(magnitude)),
        "p95": float(np.percentile(magnitude, 95)),
        "max": float(np.max(magnitude)),
    }


def _commissioning(frame: pd.DataFrame) -> dict | None:
    """|commissioned / true - 1| per unit parameter (hinge moment: |error| [N m]), or None."""
    columns = [c for c in frame.columns if c.startswith("commission_err_")]
    if not columns:
        return None
    return {c.removeprefix("commission_err_"): _spread(frame[c].to_numpy(float)) for c in columns}


def _nuisance(frame: pd.DataFrame) -> dict | None:
    """Per nuisance estimated, with its truth in the rows: |estimated - true| (hinge moment
    [N m], resistance factor [-]) and, where the rows carry its standard error, how often
    its 90 % interval ``estimate +- 1.645 se`` holds the truth and its median width; None
    when no nuisance was estimated."""
    out = {}
    for name in NUISANCE_DEFAULTS:
        if f"est_{name}" not in frame or f"true_{name}" not in frame:
            continue
        est = frame[f"est_{name}"].to_numpy(float)
        error = est - frame[f"true_{name}"].to_numpy(float)
        keep = np.isfinite(error)
        if not keep.any():
            continue
        out[name] = _spread(error[keep])
        if f"se_{name}" in frame:
            half = Z90 * frame[f"se_{name}"].to_numpy(float)[keep]
            out[name].update(
                coverage=_rate(int(np.sum(np.abs(error[keep]) <= half)), int(keep.sum())),
                median_width=float(np.median(2.0 * half)),
            )
    return out or None


def _isolation(frame: pd.DataFrame, fault: str) -> dict:
    """A per-phase fault's confusion of true and named phases, and its share named right."""
    confusion = {t: {e: 0 for e in PHASE_NAMES} for t in PHASE_NAMES}
    true_phase = np.where(
        frame[f"true_health_{fault}"] != "nominal", frame[f"true_{fault}_phase"], "none"
    )
    for t, e in zip(true_phase, frame[f"est_{fault}_phase"]):
        confusion[t][e] += 1
    faulty = [t for t in true_phase if t != "none"]
    right = sum(confusion[t][t] for t in PHASES)
    return {"confusion": confusion, "cases": len(faulty), "correct_rate": _rate(right, len(faulty))}


def _isolation_markdown(fault: str, isolation: dict) -> str:
    confusion = isolation["confusion"]
    matrix = "\n".join(
        f"| {t} | " + " | ".join(str(confusion[t][e]) for e in PHASE_NAMES) + " |"
        for t in PHASE_NAMES
    )
    return f"""## {fault.replace("_", "-").capitalize()} isolation

Rows: true faulty phase; columns: phase named by the verdict. Correct on
{_cell(isolation["correct_rate"], "{:.0%}")} of {isolation["cases"]} faulty cases.

| true \\ named | {" | ".join(PHASE_NAMES)} |
|---|---|---|---|---|
{matrix}

"""


def regression_figures(summary: dict) -> dict[str, tuple[float | None, str]]:
    """The figures ``--baseline`` compares: name -> (value, "lower"|"higher" is better)."""
    figures: dict[str, tuple[float | None, str]] = {}
    for quantity, stats in summary["errors"].items():
        for key in ("median", "p95"):
            figures[f"errors.{quantity}.{key}"] = (stats[key], "lower")
    for fault, stats in summary["detection"].items():
        figures[f"detection.{fault}.rate"] = (stats["rate"], "higher")
    figures["false_alarms.rate"] = (summary["false_alarms"]["rate"], "lower")
    for fault, isolation in summary["isolation"].items():
        figures[f"isolation.{fault}.correct_rate"] = (isolation["correct_rate"], "higher")
    return figures


def _allowed(name: str, base: float, better: str) -> float:
    if better == "higher":
        return base - RATE_SLACK
    if name.startswith("errors."):
        quantity = name.split(".")[1]
        bar = ACCURACY[quantity].tolerance
        floor = ERROR_FLOOR * bar if bar is not None else ERROR_FLOOR * 0.5  # phase: 0.05 rad
        return base * (1.0 + ERROR_GROWTH) + floor
    return base + RATE_SLACK


def compare(summary: dict, baseline: dict) -> list[str]:
    """Figures of ``summary`` worse than ``baseline`` beyond their tolerance, one line each."""
    ours = regression_figures(summary)
    theirs = regression_figures(baseline)
    worse = []
    for name, (base, better) in theirs.items():
        value = ours.get(name, (None, better))[0]
        if base is None or value is None:
            continue
        limit = _allowed(name, base, better)
        if (better == "lower" and value > limit) or (better == "higher" and value < limit):
            sign = ">" if better == "lower" else "<"
            worse.append(f"{name}: {value:.4g} {sign} allowed {limit:.4g} (baseline {base:.4g})")
    return worse


def _environment_text(summary: dict) -> str:
    """The machine and libraries the summary was computed on, as a clause (none in a summary
    written before they were recorded)."""
    found = summary.get("environment")
    if not found:
        return ""
    libraries = ", ".join(f"{k} {v}" for k, v in found.items() if k not in ("machine", "cpu"))
    return f" on {found.get('machine')} ({found.get('cpu')} CPU) with {libraries}"


def _cell(value, fmt: str = "{:.3g}") -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "—"
    return fmt.format(value)


def markdown(summary: dict) -> str:
    """summary.md from summary.json: the tables of :func:`summarize` and the run's
    provenance (campaign, hash, scenario, parameters, seed) for a person, figures embedded."""
    rows = []
    for quantity, s in summary["errors"].items():
        rows.append(
            f"| {quantity} | {s['measure']} [{s['unit']}] | {s['n']} | {_cell(s['bias'])} | "
            f"{_cell(s['median'])} | {_cell(s['p95'])} | {_cell(s['max'])} | "
            f"{_cell(s['tolerance'])} | {_cell(s['within_tolerance'], '{:.0%}')} |"
        )
    detection = "\n".join(
        f"| {f} | {d['cases']} | {d['detected']} | {_cell(d['rate'], '{:.0%}')} | "
        f"{_cell(summary['false_alarms']['per_fault_on_healthy'][f], '{:.0%}')} | "
        f"{_cell(summary['false_alarms']['per_fault_where_absent'][f], '{:.0%}')} |"
        for f, d in summary["detection"].items()
    )
    isolation = "".join(_isolation_markdown(f, i) for f, i in summary["isolation"].items())
    fa = summary["false_alarms"]
    failures = summary.get("failed", 0)
    return f"""# Campaign {summary["campaign"]}: {summary["cases"]} cases

Campaign `{summary["campaign_file"]}` (hash `{summary["campaign_hash"][:12]}`), base scenario
`{summary["scenario"]}`, parameter set `{summary["parameters"]}`, seed {summary["seed"]},
emaprog {summary["emaprog_version"]}{_environment_text(summary)}. Finished cases: {summary["cases"]} of {summary["planned"]};
failed: {failures}{" (see failures/)" if failures else ""}.

## Identification error

Error = estimate - truth (friction relative to its true value). Statistics on |error|;
"within" is the share inside the tolerance. The eccentricity phase counts only
cases whose true zeta reaches the incipient threshold.

| quantity | measure | n | bias | median | p95 | max | tolerance | within |
|---|---|---|---|---|---|---|---|---|
{chr(10).join(rows)}

![parity plots](parity.png)

![error histograms](errors.png)

## Detection and false alarms

Detected: verdict incipient or degraded where the true fault reaches its incipient
threshold. False alarms: on the {fa["healthy_cases"]} all-healthy cases
({fa["flagged"]} flagged, rate {_cell(fa["rate"], "{:.0%}")}), and over every case where the
fault is truly below its incipient threshold.

| fault | faulty cases | detected | detection rate | false alarms (healthy cases) | false alarms (fault absent) |
|---|---|---|---|---|---|
{detection}

{isolation}{_intervals_markdown(summary)}{_commissioning_markdown(summary)}Median time per case: simulate {_cell(summary["timing"]["median_simulate_s"], "{:.2f}")} s,
identify {_cell(summary["timing"]["median_identify_s"], "{:.2f}")} s.
"""


def _intervals_markdown(summary: dict) -> str:
    block = summary.get("intervals")
    if not block:
        return ""
    rows = "\n".join(
        f"| {name} | {s['n']} | {_cell(s['coverage'], '{:.0%}')} | "
        f"{_cell(s['median_width'])} | {_cell(s['width_bar'])} |"
        for name, s in block["quantities"].items()
    )
    inconclusive = ", ".join(f"{f} {_cell(r, '{:.0%}')}" for f, r in block["inconclusive"].items())
    return (
        "## Confidence\n\nShare of cases whose 90 % interval holds the truth (target "
        "85-95 %), and the interval's median width (friction relative to its true value) "
        "beside twice the tolerance.\n\n| quantity | n | coverage | median width | "
        "2 x tolerance |\n|---|---|---|---|---|\n"
        + rows
        + f"\n\nInconclusive verdicts: {inconclusive}.\n\n"
    )


def _commissioning_markdown(summary: dict) -> str:
    blocks = []
    if summary.get("commissioning"):
        rows = "\n".join(
            f"| {name} | {s['n']} | {_cell(s['median'])} | {_cell(s['p95'])} | {_cell(s['max'])} |"
            for name, s in summary["commissioning"].items()
        )
        blocks.append(
            "## Commissioning\n\nEach case's unit commissioned from its own healthy "
            "recordings (the campaign's `commission`): |commissioned / true - 1| per "
            "parameter (hinge moment: |error| [N m], the first recording's).\n\n| parameter | n | median | p95 | max |\n|---|---|---|---|---|\n"
            + rows
            + "\n\n"
        )
    for name, s in (summary.get("nuisance") or {}).items():
        nuisance = NUISANCES[name]
        label = nuisance.label.capitalize()
        unit = "" if nuisance.unit == "-" else f" {nuisance.unit}"
        held = (
            ""
            if s.get("coverage") is None
            else f"; its 90 % interval held the truth in {_cell(s['coverage'], '{:.0%}')} "
            f"(median width {_cell(s['median_width'])}{unit})"
        )
        blocks.append(
            f"{label} estimated as a nuisance: |error| median {_cell(s['median'])}, "
            f"p95 {_cell(s['p95'])}, max {_cell(s['max'])}{unit} over {s['n']} cases"
            f"{held}.\n\n"
        )
    return "".join(blocks)
