"""Command and load profiles as pure functions on a time grid (float64 arrays)."""

from __future__ import annotations

import math

import numpy as np

from .config.scenario import (
    ChirpCommand,
    ConstantCommand,
    ConstantLoad,
    NoLoad,
    RampCommand,
    SineCommand,
    SpringLoad,
    StepCommand,
)


def time_grid(duration: float, rate: float) -> np.ndarray:
    """Sample instants [s] of a run: ``0, 1/rate, ...`` strictly below ``duration``."""
    n = int(round(duration * rate))
    return np.arange(n, dtype=np.float64) / rate


def covering_grid(last: float, rate: float) -> np.ndarray:
    """The controller grid ``0, 1/rate, ...`` that covers a recording's last instant ``last``
    [s after its first sample] (the models run on it; recorded instants fall between)."""
    n = int(math.ceil(last * rate - 1e-9)) + 1
    return np.arange(n, dtype=np.float64) / rate


def chirp(t: np.ndarray, amplitude: float, f0: float, f1: float, duration: float) -> np.ndarray:
    """Linear chirp ``A sin(2 pi (f0 t + (f1 - f0) t^2 / (2 T)))`` [rad].

    Its instantaneous frequency ``f0 + (f1 - f0) t / T`` sweeps from ``f0`` at
    ``t = 0`` to ``f1`` at ``t = T``.
    """
    phase = 2.0 * np.pi * (f0 * t + 0.5 * (f1 - f0) * t * t / duration)
    return amplitude * np.sin(phase)


def command(spec, t: np.ndarray, duration: float) -> np.ndarray:
    """Position command on the surface angle [rad] at the instants ``t``."""
    if isinstance(spec, StepCommand):
        out = np.where(t >= spec.time, spec.amplitude, 0.0)
    elif isinstance(spec, RampCommand):
        out = spec.rate * np.maximum(t - spec.time, 0.0)
    elif isinstance(spec, SineCommand):
        out = spec.amplitude * np.sin(2.0 * np.pi * spec.frequency * t)
    elif isinstance(spec, ChirpCommand):
        out = chirp(t, spec.amplitude, spec.start_frequency, spec.end_frequency, duration)
    elif isinstance(spec, ConstantCommand):
        out = np.zeros_like(t)
    else:  # the schema admits no other kind
        raise TypeError(f"unknown command {spec!r}")
    return np.asarray(out + spec.offset, dtype=np.float64)


def load(spec, t: np.ndarray) -> tuple[np.ndarray, float]:
    """Aerodynamic hinge moment: constant part [N m] on ``t`` and spring rate [N m/rad].

    The moment opposes positive surface deflection:
    ``T_load = torque + stiffness * theta_surface``.
    """
    if isinstance(spec, NoLoad):
        return np.zeros_like(t), 0.0
    if isinstance(spec, ConstantLoad):
        return np.full_like(t, spec.torque), 0.0
    if isinstance(spec, SpringLoad):
        return np.full_like(t, spec.torque), float(spec.stiffness)
    raise TypeError(f"unknown load {spec!r}")


def noise_sigma(x: np.ndarray, lsb: float) -> float:
    """Standard deviation of a signal's white noise, from the signal itself [its unit].

    The second difference removes what is slow (a 10 Hz chirp moves the
    position by 2e-6 rad between 0.1 ms samples) and multiplies white noise's
    variance by 6; the median absolute value (x 1.4826) ignores the steps at
    commutations. The ADC's rounding (``lsb^2 / 12``) is the least noise a
    recorded signal can carry.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.size < 3:
        return lsb / math.sqrt(12.0)
    d2 = x[2:] - 2.0 * x[1:-1] + x[:-2]
    sigma = 1.4826 * float(np.median(np.abs(d2))) / math.sqrt(6.0)
    return math.sqrt(sigma**2 + lsb**2 / 12.0)


def command_start(time: np.ndarray, command: np.ndarray) -> float:
    """When the command leaves its first value [s after the first sample]: the end of a
    pre-roll at rest (0 when the command moves from the start). The last sample still at
    the first value before it departs by 0.1 % of the command's range."""
    span = float(np.ptp(command))
    if span <= 0.0:
        return 0.0
    away = np.flatnonzero(np.abs(command - command[0]) > 1e-3 * span)
    if away.size == 0:
        return 0.0
    still = np.flatnonzero(np.abs(command[: away[0]] - command[0]) <= 1e-9 * span + 1e-15)
    return float(time[still[-1]] - time[0]) if still.size else 0.0


def head_samples(time: np.ndarray, seconds: float = 1e-3) -> int:
    """How many samples from the first one cover ``seconds`` (at least 2): the stretch over
    which a recording's starting state (at rest, loaded, at its command) is judged."""
    time = np.asarray(time, dtype=np.float64)
    return max(2, int(np.searchsorted(time, time[0] + seconds)))


def correlation_length(residual: np.ndarray, blocks: list[int]) -> float:
    """Samples per independent residual: the integrated autocorrelation time [samples].

    The residual of a fit to real data is not white: the 1 ms mean correlates
    neighbours, and what the Monitor does not model (the Reference's switching, a
    real unit's unmodelled effects) runs over many milliseconds. Standard errors
    from ``s^2 (J^T J)^-1`` count every sample as independent and would be
    optimistic by the square root of this length. Per block (recording x signal):
    ``1 + 2 sum rho_k`` up to the first non-positive autocorrelation; the
    mean over the blocks, weighted by their length.
    """
    lengths, weights = [], []
    for part in np.split(residual, np.cumsum(blocks)[:-1]):
        x = part - part.mean()
        n = x.size
        if n < 2:
            continue
        spectrum = np.fft.rfft(x, 2 * n)
        acf = np.fft.irfft(spectrum * np.conj(spectrum))[:n]
        if acf[0] <= 0:
            continue
        rho = acf / acf[0]
        stop = np.flatnonzero(rho <= 0)
        k = int(stop[0]) if stop.size else n
        lengths.append(1.0 + 2.0 * float(np.sum(rho[1:k])))
        weights.append(n)
    return float(np.average(lengths, weights=weights)) if lengths else 1.0
