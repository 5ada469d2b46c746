"""Trend analysis of a degradation history: per-fault fit, RUL distribution, prognostic metrics."""

from __future__ import annotations

import math

import numpy as np

from .. import __version__
from ..config.parameters import Parameters
from ..faults import FAULT_NAMES, FAULTS
from .fit import BOOTSTRAP, MIN_POINTS, alpha_lambda, predict, prognostic_horizon, relative_accuracy
from .history import HistoryTable

ALPHA = 0.2  # [-] half width of the alpha-lambda cone around the true RUL


def _finite(x: float) -> float | None:
    """JSON has no infinity: a RUL beyond the prognosis horizon is written as null."""
    return float(x) if math.isfinite(x) else None


#: Inspections with the fault detected that a growth law needs: from one detection (a step
#: from nominal to faulty) any law is a guess, and the bootstrap's interval only reflects the
#: inspections' own scatter (0, 500, 1000 h with the last one faulty gave "111 h, 90 %:
#: 107-116 h").
MIN_DETECTED = 2


def analyse(table: HistoryTable, params: Parameters, law: str = "auto") -> dict:
    """The trend.json content of a history (see :mod:`emaprog.prognosis.fit` for the method).

    Per fault: the first inspection whose estimate reached the ``incipient``
    threshold; from then on (status "tracked") the growth law fitted to all
    inspections and the RUL to the parameter set's ``failure`` threshold as
    median and 90 % interval [h] (null: not reached within the horizon), and
    the RUL predicted after each inspection since the detection from the
    inspections so far. A fault never detected is not extrapolated (status
    "not detected", no RUL): noise around zero is no degradation. With a known truth
    (synthetic histories), the true RUL and the prognostic metrics: relative
    accuracy (last and mean over the predictions), the share of predictions
    inside the +/- 20 % alpha-lambda cone, the prognostic horizon [h] and
    whether the last 90 % interval covers the truth.
    """
    usage = table.usage
    faults = {}
    for index, fault in enumerate(FAULT_NAMES):
        limits = getattr(params.spec.health, fault)
        s = table.severity[fault]
        detected = np.flatnonzero(s >= limits.incipient)
        entry = {
            "status": "not detected",
            "law": None,
            "a": None,
            "b": None,
            "sigma": None,
            "threshold": limits.failure,
            "incipient": limits.incipient,
            "detected_at": float(usage[detected[0]]) if detected.size else None,
            "rul": {"median": None, "low": None, "high": None},
            "failure_at": None,
            "severity": s.tolist(),
            "predictions": [],
            "truth": None,
            "metrics": None,
        }
        if table.truth is not None:
            entry["truth"] = table.truth[fault].tolist()
        faults[fault] = entry
        if not detected.size:
            continue
        if detected.size < MIN_DETECTED:
            entry["status"] = "insufficient history"
            entry["note"] = (
                f"detected at {detected.size} inspection(s) only: a growth law and "
                f"its remaining useful life rest on at least {MIN_DETECTED} "
                "inspections with the fault detected; inspect again"
            )
            continue
        floor = inspection_sigma(table, fault)
        last = predict(usage, s, limits.failure, law, seed=index, noise_floor=floor)
        history = []
        for k in range(max(MIN_POINTS, int(detected[0]) + 1), usage.size + 1):
            p = (
                last
                if k == usage.size
                else predict(
                    usage[:k],
                    s[:k],
                    limits.failure,
                    law,
                    seed=1000 * index + k,
                    noise_floor=floor[:k],
                )
            )
            history.append(
                {
                    "usage": float(usage[k - 1]),
                    "median": _finite(p.rul_median),
                    "low": _finite(p.rul_low),
                    "high": _finite(p.rul_high),
                }
            )
        entry.update(
            {
                "status": "failed" if s[-1] >= limits.failure else "tracked",
                "law": last.fit.law,
                "a": last.fit.a,
                "b": last.fit.b,
                "sigma": last.fit.sigma,
                "rul": {
                    "median": _finite(last.rul_median),
                    "low": _finite(last.rul_low),
                    "high": _finite(last.rul_high),
                },
                "failure_at": _finite(last.now + last.rul_median),
                "predictions": history,
                "uncertainty": _uncertainty(table, fault),
            }
        )
        if table.truth is not None:
            failure = table.failure_usage.get(fault, math.inf) if table.failure_usage else math.inf
            entry["metrics"] = _metrics(history, failure, last)
    return {
        "actuator": table.actuator,
        "source": table.source,
        "inspections": int(usage.size),
        "usage": usage.tolist(),
        "faults": faults,
        "settings": {"law": law, "bootstrap": BOOTSTRAP, "interval": [5, 95], "alpha": ALPHA},
        "parameters": params.source_file,
        "emaprog_version": __version__,
    }


def inspection_sigma(table: HistoryTable, fault: str) -> np.ndarray:
    """Each inspection's severity standard deviation: its own (from its report's 90 %
    interval), else the campaign figure :attr:`~emaprog.faults.Fault.identification_sigma`."""
    fallback = FAULTS[fault].identification_sigma
    own = table.sigma[fault] if table.sigma is not None else np.full(table.usage.size, np.nan)
    return np.where(np.isfinite(own), own, fallback)


def _uncertainty(table: HistoryTable, fault: str) -> str:
    own = table.sigma[fault] if table.sigma is not None else np.full(table.usage.size, np.nan)
    count = int(np.isfinite(own).sum())
    if count == own.size:
        return "each inspection's own interval"
    if count == 0:
        return "the campaign figure (no inspection carries an interval)"
    return f"each inspection's own interval ({count} of {own.size}), else the campaign figure"


def _metrics(history: list[dict], failure: float, last) -> dict:
    """Prognostic metrics against the true failure usage (inf: the fault never fails)."""
    true_rul = failure - last.now
    if not math.isfinite(failure):
        return {
            "true_failure_at": None,
            "true_rul": None,
            "covered": not math.isfinite(last.rul_high),
            "relative_accuracy": None,
            "mean_relative_accuracy": None,
            "alpha_lambda_share": None,
            "prognostic_horizon": None,
        }
    usage = np.array([h["usage"] for h in history])
    predicted = np.array([h["median"] if h["median"] is not None else math.inf for h in history])
    before = usage < failure
    accuracy = [relative_accuracy(p, failure - u) for u, p in zip(usage[before], predicted[before])]
    inside = [alpha_lambda(p, failure - u, ALPHA) for u, p in zip(usage[before], predicted[before])]
    return {
        "true_failure_at": failure,
        "true_rul": max(true_rul, 0.0),
        "covered": bool(last.rul_low <= max(true_rul, 0.0) <= last.rul_high),
        "relative_accuracy": relative_accuracy(last.rul_median, true_rul) if true_rul > 0 else None,
        "mean_relative_accuracy": float(np.mean(accuracy)) if accuracy else None,
        "alpha_lambda_share": float(np.mean(inside)) if inside else None,
        "prognostic_horizon": prognostic_horizon(usage[before], predicted[before], failure, ALPHA),
    }
