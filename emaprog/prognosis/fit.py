"""Prognosis: fit each fault's growth over usage and predict the remaining useful life (RUL).

A fault's *severity* is the scalar its health thresholds apply to
(:func:`emaprog.identification.result.severity`: ``|k_f - 1|``, backlash,
worst-phase shorted fraction, zeta). Across inspections at usage ``u`` [flight
hours] it is fitted by one of two growth laws:

* linear, ``s(u) = a + b u``;
* exponential, ``s(u) = a exp(b u)`` (wear that feeds on itself: a shorted
  turn heats its neighbours, a worn joint hammers).

``auto`` takes the law with the lower AIC. Uncertainty comes from a
parametric bootstrap of the least-squares fit: Gaussian errors are added to
the fitted curve and the law refitted, :data:`BOOTSTRAP` times. Their standard
deviation is the larger of the fit's residual spread and the identification's
own accuracy (``noise_floor``): a handful of inspections that happen to lie on
a line must not promise a sharper RUL than the estimates behind them allow.
Chosen over the parameter covariance (delta method) because the threshold
crossing time is a strongly nonlinear function of the parameters -- the
bootstrap gives its skewed distribution directly -- and over a Bayesian fit
because it needs no prior and no extra dependency. Each replicate's crossing
of the failure threshold gives one RUL sample; the report gives the median and
the 90 % interval (5th-95th percentile).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.optimize import curve_fit

LAWS = ("linear", "exponential")
BOOTSTRAP = 400  # replicates of the residual bootstrap
HORIZON = 1.0e6  # [h] a crossing later than this is "not within sight" (RUL = inf)
MIN_POINTS = 3  # inspections needed before a fit is attempted


def growth(law: str, usage: np.ndarray, a: float, b: float) -> np.ndarray:
    """Severity along usage for a law's parameters [-] or [rad]."""
    if law == "linear":
        return a + b * usage
    return a * np.exp(np.clip(b * usage, -700.0, 700.0))


def crossing(law: str, a: float, b: float, threshold: float) -> float:
    """Usage at which the law reaches ``threshold`` [h]; inf if it never does."""
    if law == "linear":
        if a >= threshold:
            return -math.inf
        return (threshold - a) / b if b > 0 else math.inf
    if a <= 0.0:
        return math.inf
    if a >= threshold:
        return -math.inf
    return math.log(threshold / a) / b if b > 0 else math.inf


def _fit_one(law: str, usage: np.ndarray, severity: np.ndarray) -> tuple[float, float]:
    if law == "linear":
        b, a = np.polyfit(usage, severity, 1)
        return float(a), float(b)
    positive = severity > 0
    if positive.sum() >= 2:  # start from the log-linear fit of the positive points
        b0, log_a0 = np.polyfit(usage[positive], np.log(severity[positive]), 1)
        start = (math.exp(log_a0), b0)
    else:
        start = (max(float(np.mean(severity)), 1e-9), 0.0)
    try:
        (a, b), _ = curve_fit(
            lambda u, a, b: growth("exponential", u, a, b), usage, severity, p0=start, maxfev=2000
        )
    except (RuntimeError, ValueError):  # no convergence: the log-linear start is the fit
        a, b = start
    return float(a), float(b)


GAUSS_NEWTON_STEPS = 12  # from the fit of the data every replicate is a small step away


def _refit_replicates(
    best: TrendFit, usage: np.ndarray, replicates: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares law parameters of every bootstrap replicate (rows), all at once.

    Linear: one ``lstsq`` for all rows. Exponential: Gauss-Newton on
    ``a exp(b u)`` started from the data's fit ``best`` (usage scaled to [0, 1]
    for conditioning), vectorised over the replicates.
    """
    if best.law == "linear":
        design = np.column_stack([np.ones_like(usage), usage])
        (a, b), *_ = np.linalg.lstsq(design, replicates.T, rcond=None)
        return a, b
    scale = max(float(usage.max()), 1.0)
    x = usage / scale
    a = np.full(replicates.shape[0], best.a)
    b = np.full(replicates.shape[0], best.b * scale)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for _ in range(GAUSS_NEWTON_STEPS):
            e = np.exp(np.clip(b[:, None] * x, -700.0, 700.0))
            model = a[:, None] * e
            residual = replicates - model
            ja, jb = e, model * x
            a11, a12, a22 = (ja * ja).sum(1), (ja * jb).sum(1), (jb * jb).sum(1)
            g1, g2 = (ja * residual).sum(1), (jb * residual).sum(1)
            damping = 1e-9 * (a11 + a22)
            det = (a11 + damping) * (a22 + damping) - a12 * a12
            a = a + ((a22 + damping) * g1 - a12 * g2) / det
            b = b + ((a11 + damping) * g2 - a12 * g1) / det
    return np.nan_to_num(a, nan=0.0), np.nan_to_num(b / scale, nan=0.0)


class TrendFit(NamedTuple):
    law: str
    a: float
    b: float
    sigma: float  # [same unit as severity] residual standard deviation
    aic: float


def fit(usage: np.ndarray, severity: np.ndarray, law: str = "auto") -> TrendFit:
    """Least-squares growth law through the inspections (``auto``: lower AIC)."""
    usage, severity = np.asarray(usage, float), np.asarray(severity, float)
    candidates = LAWS if law == "auto" else (law,)
    best = None
    n = usage.size
    for name in candidates:
        a, b = _fit_one(name, usage, severity)
        residual = severity - growth(name, usage, a, b)
        rss = float(np.sum(residual**2))
        sigma = math.sqrt(rss / max(n - 2, 1))
        aic = n * math.log(max(rss / n, 1e-300)) + 4.0
        if best is None or aic < best.aic:
            best = TrendFit(name, a, b, sigma, aic)
    assert best is not None  # the laws are tried in turn: the first one always fits
    return best


class Prediction(NamedTuple):
    fit: TrendFit
    threshold: float
    now: float  # [h] usage of the last inspection
    rul_median: float  # [h] inf when the fault does not grow towards the threshold
    rul_low: float  # [h] 5th percentile
    rul_high: float  # [h] 95th percentile
    samples: np.ndarray  # [h] bootstrap RUL samples (inf where no crossing)


def predict(
    usage: np.ndarray,
    severity: np.ndarray,
    threshold: float,
    law: str = "auto",
    seed: int = 0,
    noise_floor: float | np.ndarray = 0.0,
) -> Prediction:
    """RUL to ``threshold`` from the last inspection, with its bootstrap distribution.

    A fault already past the threshold has RUL 0. The bootstrap adds Gaussian
    errors of standard deviation ``max(residual spread, noise_floor)`` to the
    chosen law's fit (``numpy.random.Generator`` from ``seed``); ``noise_floor``
    is one figure or each inspection's own (its identification's uncertainty).
    """
    usage, severity = np.asarray(usage, float), np.asarray(severity, float)
    if usage.size < MIN_POINTS:
        raise ValueError(f"a trend needs at least {MIN_POINTS} inspections, got {usage.size}")
    best = fit(usage, severity, law)
    now = float(usage[-1])
    fitted = growth(best.law, usage, best.a, best.b)
    spread = np.maximum(best.sigma, np.broadcast_to(np.asarray(noise_floor, float), fitted.shape))
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    replicates = fitted + rng.normal(0.0, spread, size=(BOOTSTRAP, fitted.size))
    a, b = _refit_replicates(best, usage, replicates)
    samples = np.array([crossing(best.law, ai, bi, threshold) for ai, bi in zip(a, b)]) - now
    samples = np.clip(samples, 0.0, 2.0 * HORIZON)  # past the horizon: kept finite to rank
    low, median, high = (float(np.percentile(samples, q)) for q in (5, 50, 95))
    low, median, high = (x if x <= HORIZON else math.inf for x in (low, median, high))
    samples = np.where(samples > HORIZON, math.inf, samples)
    return Prediction(best, threshold, now, median, low, high, samples)


# ---------------------------------------------------------------- prognostic metrics
def relative_accuracy(predicted: float, true: float) -> float:
    """RA = 1 - |RUL_true - RUL_pred| / RUL_true (Saxena et al.) [-]."""
    if not math.isfinite(predicted) or true <= 0:
        return 0.0 if true > 0 else float(predicted == 0)
    return 1.0 - abs(true - predicted) / true


def alpha_lambda(predicted: float, true: float, alpha: float = 0.2) -> bool:
    """Whether the prediction lies within +/- alpha of the true RUL (the alpha-lambda cone)."""
    return math.isfinite(predicted) and abs(predicted - true) <= alpha * true


def prognostic_horizon(
    usage: np.ndarray, predicted: np.ndarray, true_failure: float, alpha: float = 0.2
) -> float:
    """Usage-to-failure left when the predictions enter the +/- alpha cone for good [h].

    0 when they never do (or only at the last inspection before the failure).
    """
    inside = [alpha_lambda(p, true_failure - u, alpha) for u, p in zip(usage, predicted)]
    for k in range(len(inside)):
        if all(inside[k:]):
            return float(true_failure - usage[k])
    return 0.0
