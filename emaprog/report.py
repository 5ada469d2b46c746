"""Figures and markdown from stored results (never re-simulates)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .faults import CATALOGUE, FAULTS, NUISANCES, PHASE_FAULTS, QUANTITIES, Quantity  # noqa: E402
from .identification.confidence import MIN_PHASE_CONFIDENCE  # noqa: E402
from .io.storage import Trace  # noqa: E402


def plot_trace(trace: Trace, path: str | Path, title: str = "") -> Path:
    """Command/position, speed and current of a trace (+ phase currents if present)."""
    c = trace.columns
    t = c["time"]
    phases = all(f"current_{x}" in c for x in "abc")
    rows = 4 if phases else 3
    fig, ax = plt.subplots(rows, 1, figsize=(10, 2.4 * rows), sharex=True)
    ax[0].plot(t, c["command"], label="command")
    ax[0].plot(t, c["position"], label="position (measured)")
    ax[0].set_ylabel("surface [rad]")
    ax[0].legend(loc="upper right")
    ax[1].plot(t, c["speed"], color="tab:green")
    ax[1].set_ylabel("motor speed [rad/s]")
    ax[2].plot(t, c["current"], color="tab:red", lw=0.8)
    ax[2].set_ylabel("equivalent current [A]")
    if phases:
        for x in "abc":
            ax[3].plot(t, c[f"current_{x}"], lw=0.7, label=f"phase {x.upper()}")
        ax[3].set_ylabel("phase currents [A]\n(period means)")
        ax[3].legend(loc="upper right")
    ax[-1].set_xlabel("time [s]")
    fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_fit(
    trace: Trace,
    identified: dict[str, np.ndarray],
    measured_width: int,
    model_width: int,
    path: str | Path,
    residual: np.ndarray | None = None,
    floor: float | None = None,
) -> Path:
    """Measured vs identified Monitor current (both over the fitness's 1 ms) and position;
    with ``residual`` (the fitted current error at the recorded instants [A]) a third panel
    draws it against the recording's noise floor ``floor`` (1 ms mean of its noise, 1 sigma).

    The measurement is drawn at its own instants (relative to its first sample), the
    Monitor on its controller grid (``identified["time"]``).
    """
    from .identification.objective import low_pass

    t = trace.time - trace.time[0]
    tm = identified["time"]
    panels = 2 if residual is None else 3
    fig, ax = plt.subplots(panels, 1, figsize=(10, 3 * panels), sharex=True)
    ax[0].plot(t, low_pass(trace["current"], measured_width), lw=0.9, label="measured (1 ms mean)")
    ax[0].plot(
        tm,
        low_pass(identified["current"], model_width),
        lw=0.9,
        ls="--",
        label="identified Monitor Model",
    )
    ax[0].set_ylabel("equivalent current [A]")
    ax[0].legend(loc="upper right")
    ax[1].plot(t, trace["command"], lw=0.8, color="0.5", label="command")
    ax[1].plot(t, trace["position"], lw=0.9, label="measured")
    ax[1].plot(tm, identified["position"], lw=0.9, ls="--", label="identified Monitor Model")
    ax[1].set_ylabel("surface position [rad]")
    ax[1].legend(loc="upper right")
    if residual is not None:
        ax[2].plot(
            t, residual, lw=0.8, label="residual (corrected measurement - Monitor, 1 ms mean)"
        )
        if floor is not None:
            for sign in (-2.0, 2.0):
                ax[2].axhline(
                    sign * floor,
                    color="C3",
                    ls=":",
                    lw=1.0,
                    label="noise floor (+-2 sigma)" if sign > 0 else None,
                )
        ax[2].set_ylabel("current residual [A]")
        ax[2].legend(loc="upper right")
    ax[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_convergence(logbook: list[dict], path: str | Path) -> Path:
    """GA best and mean fitness per generation (log scale)."""
    gen = [r["gen"] for r in logbook]
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.semilogy(gen, [r["best"] for r in logbook], label="best")
    ax.semilogy(gen, [r["mean"] for r in logbook], label="mean")
    ax.set_xlabel("generation")
    ax.set_ylabel("fitness [-]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def _row(q: Quantity) -> tuple[str, tuple[str, ...], str, str]:
    """(label, path in the nested report shape, unit, format) of one quantity."""
    fault = next(f for f in CATALOGUE if q in f.quantities)
    path = (fault.name,) if q.key is None else (fault.name, q.key)
    fmt = "{:.2f}" if q.circular else ("{:.2e}" if q.unit == "rad" else "{:.3f}")
    return q.label, path, q.unit, fmt


ROWS = tuple(_row(q) for q in QUANTITIES.values())


def _pick(tree: dict | None, keys: tuple[str, ...]):
    for key in keys:
        if tree is None:
            return None
        tree = tree[key]
    return tree


def _fmt(value, fmt: str) -> str:
    return "—" if value is None else fmt.format(value)


def identification_summary(report: dict) -> str:
    health = ", ".join(f"{fault} {verdict}" for fault, verdict in report["health"].items())
    lines = [f"health: {health}"]
    for fault in PHASE_FAULTS:
        verdict = report["health"].get(fault)
        phase = report.get(f"{fault}_phase")
        isolation = report["confidence"]["isolation"].get(fault)
        if verdict == "inconclusive" and phase:
            # a suspect phase is only named with its isolation (confidence.named_phase)
            lines.append(
                f"{FAULTS[fault].label} inconclusive at its threshold: suspect phase "
                f"{phase.upper()} (confidence {isolation['confidence']:.0%})"
            )
        if verdict not in ("incipient", "degraded"):
            continue
        if not phase and isolation:
            lines.append(
                f"{FAULTS[fault].label}: phase not determined, "
                f"{isolation['phase'].upper()} or {isolation['runner_up'].upper()} "
                f"(confidence {isolation['confidence']:.0%})"
            )
        if phase:
            channel = (report.get("phase_channels") or {}).get(phase)
            lines.append(
                f"{FAULTS[fault].label} on phase {phase.upper()}"
                + (f" (logger channel {channel})" if channel else "")
                + (f" (confidence {isolation['confidence']:.0%})" if isolation else "")
            )
    for fault, why in report["confidence"]["inconclusive"].items():
        lines.append(f"{fault} inconclusive: {why}")
    form = report.get("form") or {}
    if form and not form["calibrated"]:
        lines.append(f"form: {form['note']}")
    for label, keys, unit, fmt in ROWS:
        est = _fmt(_pick(report["estimate"], keys), fmt)
        interval = _pick(report["interval"], keys)
        if interval is not None:
            est += f" [{fmt.format(interval[0])}, {fmt.format(interval[1])}]"
        line = f"  {label:20s} {est:>32s} {unit}"
        if keys[0] in report["confidence"]["inconclusive"]:
            line += " (inconclusive: not a finding)"
        if report["truth"] is not None:
            line += (
                f"   (true {_fmt(_pick(report['truth'], keys), fmt)}, "
                f"error {_fmt(_pick(report['error'], keys), fmt)})"
            )
        lines.append(line)
    lines += [f"  {line}" for line in _operating_lines(report)]
    lines.append(
        f"fitness {report['fitness']:.3e} after {report['evaluations']} Monitor runs "
        f"in {report['elapsed_s']:.1f} s"
    )
    return "\n".join(lines)


#: Operating conditions estimated beside the faults: label, unit, format.
NUISANCE_ROWS = {n.name: (n.label, n.unit, n.fmt) for n in NUISANCES.values()}


def _operating_lines(report: dict) -> list[str]:
    """The estimated operating conditions (nuisances) with their intervals, one line each."""
    lines = []
    for name, value in (report.get("nuisance") or {}).items():
        label, unit, fmt = NUISANCE_ROWS[name]
        low, high = (report.get("nuisance_interval") or {}).get(name) or (None, None)
        shown = "" if low is None or high is None else f" [{fmt.format(low)}, {fmt.format(high)}]"
        lines.append(f"{label:20s} {fmt.format(value) + shown:>32s} {unit} (operating condition)")
    return lines


def _phase_sentence(report: dict) -> str:
    """Which phase each per-phase fault is on, only when it is flagged (incipient or
    degraded), or the suspect one beside an ``inconclusive`` verdict at its threshold."""
    return " ".join(_fault_phase_sentence(report, fault) for fault in PHASE_FAULTS)


def _fault_phase_sentence(report: dict, fault: str) -> str:
    label = fault.replace("_", " ")
    phase = report.get(f"{fault}_phase")
    isolation = report["confidence"]["isolation"].get(fault)
    if report["health"].get(fault) == "inconclusive" and phase:
        return (
            f"{label.capitalize()} inconclusive at its incipient threshold (its interval clear "
            f"of healthy, not of the threshold): suspect phase {phase.upper()}, its interval "
            f"apart from the runner-up phase's (confidence {isolation['confidence']:.1%} "
            f"against phase {isolation['runner_up'].upper()})."
        )
    if report["health"].get(fault) not in ("incipient", "degraded"):
        return f"No {label} flagged: no faulty phase named."
    if phase is None and isolation is not None:
        why = (
            f"below the {MIN_PHASE_CONFIDENCE:.0%} a named phase needs"
            if isolation["confidence"] < MIN_PHASE_CONFIDENCE
            else "but their 90 % intervals overlap, and on a unit of another form a named "
            "phase needs them apart"
        )
        return (
            f"{label.capitalize()} flagged, phase not determined: {isolation['phase'].upper()} "
            f"or {isolation['runner_up'].upper()} (confidence {isolation['confidence']:.0%} "
            f"for {isolation['phase'].upper()}, {why})."
        )
    if phase is None:
        return f"{label.capitalize()} flagged, phase not determined."
    channel = (report.get("phase_channels") or {}).get(phase)
    named = f"{phase.upper()}" + (f" (logger channel `{channel}`)" if channel else "")
    sentence = f"Faulty phase (largest {label}): {named}."
    check = (report.get("phase_identity") or {}).get("commissioning")
    if check:
        sentence += f" Channel identity {check}."
    if isolation is not None:
        sentence += (
            f" Confidence in phase {isolation['phase'].upper()} against phase "
            f"{isolation['runner_up'].upper()}: {isolation['confidence']:.1%} "
            f"(chi-square difference {isolation['delta_chi2']:.3g})."
        )
    return sentence


def _runs_text(ga: dict) -> str:
    """The GA runs clause of report.md: empty for one run (and for older reports)."""
    runs = ga.get("runs", 1)
    if runs <= 1:
        return ""
    return f"; the best polished fit of {runs} independent GA runs, that run's seed {ga['seed']}"


def report_markdown(report: dict) -> str:
    confidence = report["confidence"]
    truth = report["truth"] is not None
    head = "| quantity | unit | estimate | 90 % interval | GA best |" + (
        " truth | error |" if truth else ""
    )
    rule = "|---|---|---|---|---|" + ("---|---|" if truth else "")
    rows = []
    for label, keys, unit, fmt in ROWS:
        interval = _pick(report["interval"], keys)
        finding = "" if keys[0] not in confidence["inconclusive"] else " (inconclusive)"
        cells = [
            label,
            unit,
            _fmt(_pick(report["estimate"], keys), fmt) + finding,
            "—" if interval is None else f"[{fmt.format(interval[0])}, {fmt.format(interval[1])}]",
            _fmt(_pick(report["ga"]["estimate"], keys), fmt),
        ]
        if truth:
            cells += [
                _fmt(_pick(report["truth"], keys), fmt),
                _fmt(_pick(report["error"], keys), fmt),
            ]
        rows.append("| " + " | ".join(cells) + " |")
    reasons = confidence["inconclusive"]
    health = "\n".join(
        f"| {fault} | {verdict} | {reasons.get(fault, '')} |"
        for fault, verdict in report["health"].items()
    )
    floor = confidence["noise_floor"]
    ga = report["ga"]
    operating = ""
    if report.get("nuisance"):
        operating = (
            "\n## Operating conditions (estimated, no verdict)\n\n| condition | unit | "
            "estimate | 90 % interval |\n|---|---|---|---|\n"
        )
        for name, value in report["nuisance"].items():
            label, unit, fmt = NUISANCE_ROWS[name]
            low, high = (report.get("nuisance_interval") or {}).get(name) or (None, None)
            interval = (
                "—" if low is None or high is None else f"[{fmt.format(low)}, {fmt.format(high)}]"
            )
            operating += f"| {label} | {unit} | {fmt.format(value)} | {interval} |\n"
    load = report.get("load") or {}
    load_line = f"\nLoad applied to the model: {load['note']}.\n" if load.get("note") else ""
    return f"""# Fault identification: {report["scenario"] or report["trace"]}

Trace `{report["trace"]}`, parameter set `{report["parameters"]}`, emaprog {report["emaprog_version"]}.

## Health

| fault | verdict | why inconclusive |
|---|---|---|
{health}

{_phase_sentence(report)}

Fit quality: fitness {report["fitness"]:.3e} is {floor["ratio"]:.2f} x the recording's noise
floor ({floor["fitness"]:.3e}); {"explained" if floor["explained"] else "NOT explained"}
({floor["rule"]}). Intervals: {confidence["method"]}.

## Estimates

{head}
{rule}
{chr(10).join(rows)}
{operating}{load_line}
Fitness {report["fitness"]:.4e} (GA best {ga["fitness"]:.4e}; refined: {ga["refined"]}).
{ga["generations"]} generations (stopped by {ga["stopped_by"]}), {report["evaluations"]} Monitor
Model runs, {report["elapsed_s"]:.2f} s, GA seed {report["seed"]}{_runs_text(ga)}.

Nominal-discrepancy correction: {report["correction"]["applied"]} ({report["correction"]["note"]}).

Unit form: {(report.get("form") or {}).get("note", "not recorded")}.

## Figures

![measured vs identified](fit.png)

![GA convergence](convergence.png)
"""


def plot_calibration(result: dict, path: str | Path) -> Path:
    """Optimal Monitor Z per Reference zeta, with the least-squares line Z = c zeta."""
    zeta = np.array(result["zeta"])
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(zeta, result["optimal_z"], "o", label="optimal Z (Monitor vs Reference)")
    line = np.linspace(0.0, zeta.max(), 50)
    ax.plot(
        line,
        result["eccentricity_gain"] * line,
        "-",
        label=f"Z = {result['eccentricity_gain']:.3f} zeta (r² = {result['r_squared']:.4f})",
    )
    ax.set_xlabel("Reference eccentricity zeta [-]")
    ax.set_ylabel("Monitor shape amplitude Z [-]")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


QUANTITY_LABELS = {name: f"{q.label} [{q.unit}]" for name, q in QUANTITIES.items()}


def plot_parity(frame, path: str | Path) -> Path:
    """True vs estimated value of every fault quantity over a campaign's cases."""
    fig, axes = plt.subplots(2, 4, figsize=(14, 6.5))
    healthy = frame["healthy_case"].to_numpy(bool)
    for ax, (quantity, label) in zip(axes.flat, QUANTITY_LABELS.items()):
        true, est = (
            frame[f"true_{quantity}"].to_numpy(float),
            frame[f"est_{quantity}"].to_numpy(float),
        )
        ax.plot(true[~healthy], est[~healthy], "o", ms=3.5, alpha=0.7, label="faulty cases")
        ax.plot(true[healthy], est[healthy], "x", ms=4, color="tab:green", label="healthy cases")
        lo = float(min(true.min(initial=0.0), est.min(initial=0.0)))
        hi = float(max(true.max(initial=1e-12), est.max(initial=1e-12)))
        ax.plot([lo, hi], [lo, hi], "-", color="0.4", lw=0.8)
        ax.set_title(label, fontsize=9)
        ax.set_xlabel("true", fontsize=8)
        ax.set_ylabel("estimated", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
    axes.flat[0].legend(fontsize=7)
    axes.flat[-1].axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def plot_error_histograms(
    errors: dict[str, np.ndarray], tolerances: dict[str, float | None], path: str | Path
) -> Path:
    """Histogram of each quantity's error with its tolerance band."""
    fig, axes = plt.subplots(2, 4, figsize=(14, 6.5))
    for ax, (quantity, values) in zip(axes.flat, errors.items()):
        if values.size:
            ax.hist(values, bins=min(30, max(5, values.size // 2)), color="tab:blue", alpha=0.8)
        bar = tolerances.get(quantity)
        if bar is not None:
            for x in (-bar, bar):
                ax.axvline(x, color="tab:red", ls="--", lw=0.9)
        ax.set_title(
            QUANTITY_LABELS[quantity].replace("[-]", "error").replace("[rad]", "error [rad]")
            + (" (rel.)" if QUANTITIES[quantity].measure == "relative" else ""),
            fontsize=9,
        )
        ax.set_ylabel("cases", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
    axes.flat[-1].axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


SEVERITY_LABELS = {f.name: f.severity for f in CATALOGUE}


def plot_trend(result: dict, path: str | Path) -> Path:
    """Estimated severity vs usage per fault: fit, failure threshold, RUL interval, truth."""
    from .prognosis.fit import growth

    usage = np.array(result["usage"])
    fig, axes = plt.subplots(2, 2, figsize=(12, 7.5))
    for ax, (fault, entry) in zip(axes.flat, result["faults"].items()):
        ax.plot(usage, entry["severity"], "o", ms=4, label="estimated")
        if entry["truth"] is not None:
            ax.plot(usage, entry["truth"], "-", color="0.5", lw=1, label="true")
        rul = entry["rul"]
        end = usage[-1] + (rul["high"] if rul["high"] is not None else 0.5 * np.ptp(usage))
        end = max(end, usage[-1] + 0.1 * max(np.ptp(usage), 1.0))
        grid = np.linspace(usage[0], end, 200)
        if entry["law"] is not None:
            ax.plot(
                grid,
                growth(entry["law"], grid, entry["a"], entry["b"]),
                "--",
                label=f"{entry['law']} fit",
            )
        ax.axhline(entry["threshold"], color="tab:red", lw=1, label="failure threshold")
        ax.axhline(entry["incipient"], color="tab:orange", lw=0.8, ls=":", label="incipient")
        if rul["low"] is not None:
            high = usage[-1] + (rul["high"] if rul["high"] is not None else end - usage[-1])
            ax.axvspan(
                usage[-1] + rul["low"], high, color="tab:red", alpha=0.12, label="90 % RUL interval"
            )
        if rul["median"] is not None:
            ax.axvline(usage[-1] + rul["median"], color="tab:red", ls="--", lw=0.8)
        metrics = entry["metrics"]
        if metrics and metrics["true_failure_at"] is not None:
            ax.axvline(metrics["true_failure_at"], color="k", lw=0.8, label="true failure")
        median = (
            entry["status"]
            if entry["status"] in ("not detected", "insufficient history")
            else "RUL beyond horizon"
            if rul["median"] is None
            else f"RUL {rul['median']:.0f} h"
        )
        ax.set_title(f"{SEVERITY_LABELS[fault]}: {median}", fontsize=9)
        ax.set_xlabel("usage [flight hours]", fontsize=8)
        ax.tick_params(labelsize=7)
        top = max(entry["threshold"] * 1.3, max(entry["severity"]) * 1.1)
        ax.set_ylim(min(0.0, min(entry["severity"])), top)
        ax.grid(True, alpha=0.3)
    axes.flat[0].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"Degradation trend of {result['actuator']}")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def trend_markdown(result: dict) -> str:
    """trend.md: the RUL table and, for synthetic histories, the prognostic metrics."""

    def hours(x):
        return "beyond horizon" if x is None else f"{x:.0f}"

    rows, metric_rows = [], []
    for fault, e in result["faults"].items():
        if e["status"] == "not detected":
            rows.append(
                f"| {fault} | — | {e['severity'][-1]:.4g} | {e['threshold']:.4g} | never | "
                "not detected | — |"
            )
            continue
        if e["status"] == "insufficient history":
            rows.append(
                f"| {fault} | — | {e['severity'][-1]:.4g} | {e['threshold']:.4g} | "
                f"{hours(e['detected_at'])} | insufficient history | — |"
            )
            continue
        rows.append(
            f"| {fault} | {e['law']} | {e['severity'][-1]:.4g} | {e['threshold']:.4g} | "
            f"{hours(e['detected_at'])} | {hours(e['rul']['median'])} | "
            f"{hours(e['rul']['low'])} – {hours(e['rul']['high'])} |"
        )
        m = e["metrics"]
        if m is not None:
            metric_rows.append(
                f"| {fault} | {hours(m['true_rul'])} | {'yes' if m['covered'] else 'no'} | "
                f"{_fmt(m['relative_accuracy'], '{:.2f}')} | "
                f"{_fmt(m['mean_relative_accuracy'], '{:.2f}')} | "
                f"{_fmt(m['alpha_lambda_share'], '{:.0%}')} | "
                f"{_fmt(m['prognostic_horizon'], '{:.0f}')} |"
            )
    metrics = ""
    if metric_rows:
        metrics = f"""
## Against the truth (synthetic history)

Relative accuracy RA = 1 - |RUL_true - RUL| / RUL_true; alpha-lambda: share of the
predictions (one after each inspection since the detection) within +/- {result["settings"]["alpha"]:.0%} of the
true RUL; prognostic horizon: true time to failure left when the predictions enter that
cone for good.

| fault | true RUL [h] | 90 % interval covers it | RA (last) | RA (mean) | alpha-lambda | horizon [h] |
|---|---|---|---|---|---|---|
{chr(10).join(metric_rows)}
"""
    return f"""# Degradation trend: {result["actuator"]}

{result["inspections"]} inspections from {result["usage"][0]:.0f} to {result["usage"][-1]:.0f}
flight hours (`{result["source"]}`), parameter set `{result["parameters"]}`, emaprog
{result["emaprog_version"]}. Growth law per fault: {result["settings"]["law"]}
(linear or exponential, least squares; "auto" takes the lower AIC); RUL to the
failure threshold from the last inspection, median and 90 % interval of a
{result["settings"]["bootstrap"]}-replicate bootstrap whose errors are never smaller than
the identification's own accuracy. A fault whose estimate never reached its
incipient threshold is not extrapolated.

| fault | law | last severity | failure threshold | first detected [h] | RUL median [h] | RUL 90 % [h] |
|---|---|---|---|---|---|---|
{chr(10).join(rows)}
{metrics}
![trend](trend.png)
"""
