"""A recording without a command channel: the test command from a scenario, placed in time.

A logger that records the actuator's response but not its command (many rigs log the
sensors only) leaves open when the test command started. The scenario gives the command's
shape; its start is found from the response: the healthy Monitor's surface position on
the scenario's command, shifted by a delay ``tau``, is fitted to the recorded position by
least squares (the position loop follows the command closely, and a hinge moment or an
incipient fault moves the position far less than a shift of a millisecond does).

``tau`` is searched on the recording's own sample grid (the whole lag range, by FFT
cross-correlation of the mean-free signals), then refined to a fraction of a sample by the
parabola through the squared error at the best lag and its neighbours; its standard error
is ``sqrt(s^2 / (d2 / 2))`` with ``s^2`` the residual variance over the correlation length
of the residual and ``d2`` the squared error's second derivative in ``tau`` [s^2].
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .. import signals
from ..config.parameters import Parameters
from ..config.scenario import Scenario
from ..faults import healthy_values, monitor_form
from . import monitor
from .common import inputs


class Alignment(NamedTuple):
    command: np.ndarray  # [rad] the scenario's command at the recorded instants
    delay: float  # [s] the command's start after the recording's first sample
    delay_error: float  # [s] its standard error
    note: str


def align_command(
    scenario: Scenario, params: Parameters, time: np.ndarray, position: np.ndarray
) -> Alignment:
    """The scenario's command placed in the recording's time by its position response."""
    t = np.asarray(time, dtype=np.float64) - float(time[0])
    inp = inputs(scenario, params)
    model = monitor.run(
        params, inp, monitor_form(healthy_values(), params.spec.monitor.eccentricity_gain)
    )
    period = float(np.median(np.diff(t)))
    grid = np.arange(t.size) * period
    # the model's position on the recording's grid, from its own start; the command before
    # it stands at its first value, after its end at its last
    response = np.interp(grid, inp.time, model["position"])
    n_model = int(min(t.size, math.floor(inp.time[-1] / period) + 1))
    measured = np.asarray(position, dtype=np.float64)
    lag = _best_lag(measured, response[:n_model])
    delay = lag * period
    shifted = np.interp(
        t - delay,
        inp.time,
        model["position"],
        left=model["position"][0],
        right=model["position"][-1],
    )
    residual = measured - shifted
    s2 = float(np.mean(residual**2))
    step = period
    curvature = []
    for h in (-step, step):
        other = np.interp(
            t - delay - h,
            inp.time,
            model["position"],
            left=model["position"][0],
            right=model["position"][-1],
        )
        curvature.append(float(np.sum((measured - other) ** 2)))
    d2 = (curvature[0] + curvature[1] - 2.0 * float(np.sum(residual**2))) / step**2
    refine = 0.0
    if d2 > 0:
        refine = 0.5 * (curvature[0] - curvature[1]) / (d2 * step**2) * step
        refine = float(np.clip(refine, -step, step))
    delay += refine
    length = signals.correlation_length(residual, [residual.size])
    error = math.sqrt(2.0 * s2 * length / d2) if d2 > 0 else math.inf
    command = np.interp(
        t - delay, inp.time, inp.command, left=inp.command[0], right=inp.command[-1]
    )
    note = (
        f"no command channel: the command of scenario '{scenario.name}' "
        f"({scenario.command.kind}, {scenario.duration:g} s), starting {delay * 1e3:.3f} ms "
        f"after the first sample (standard error {error * 1e6:.1f} us), placed by fitting "
        "the healthy Monitor's position to the recorded position"
    )
    return Alignment(command, float(delay), float(error), note)


def _best_lag(measured: np.ndarray, response: np.ndarray) -> int:
    """The integer lag ``k`` in ``[0, n/2]`` (the command starting ``k`` samples into the
    recording) of least squared error over the whole recording: before ``k`` the model
    stands at its first value, after its end at its last. O(n log n) by FFT."""
    x = measured
    n = x.size
    r = np.concatenate([response, np.full(max(n - response.size, 0), response[-1])])[:n]
    size = 1 << int(math.ceil(math.log2(2 * n)))
    # cross[k] = sum_{t >= k} x_t r_{t-k}
    cross = np.fft.irfft(np.fft.rfft(x, size) * np.conj(np.fft.rfft(r, size)), size)[:n]
    x2 = np.concatenate([[0.0], np.cumsum(x**2)])  # x2[k] = sum_{t<k} x_t^2
    x1 = np.concatenate([[0.0], np.cumsum(x)])
    r2 = np.concatenate([[0.0], np.cumsum(r**2)])  # r2[j] = sum_{i<j} r_i^2
    k = np.arange(n)
    before = x2[k] - 2.0 * r[0] * x1[k] + k * r[0] ** 2
    after = (x2[n] - x2[k]) - 2.0 * cross + r2[n - k]
    sse = (before + after)[: n // 2 + 1]
    return int(np.argmin(sse))
