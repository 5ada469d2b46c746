"""Command and load profiles against their closed forms."""

import numpy as np
import pytest

from emaprog import signals
from emaprog.config.scenario import (
    ChirpCommand,
    ConstantLoad,
    NoLoad,
    RampCommand,
    SineCommand,
    SpringLoad,
    StepCommand,
)


def test_time_grid_is_uniform_and_stops_before_duration():
    t = signals.time_grid(0.5, 10_000.0)
    assert t.size == 5000 and t[0] == 0.0 and t[-1] < 0.5
    assert np.allclose(np.diff(t), 1e-4)


def test_chirp_instantaneous_frequency_sweeps_from_start_to_end():
    rate, duration, f0, f1 = 100_000.0, 2.0, 0.5, 10.0
    t = signals.time_grid(duration, rate)
    x = signals.command(
        ChirpCommand(kind="chirp", amplitude=0.05, start_frequency=f0, end_frequency=f1),
        t,
        duration,
    )
    # instantaneous frequency from successive zero crossings (half periods), interpolated
    k = np.nonzero(np.sign(x[:-1]) * np.sign(x[1:]) < 0)[0]
    crossings = t[k] - x[k] * (t[k + 1] - t[k]) / (x[k + 1] - x[k])
    mid = 0.5 * (crossings[1:] + crossings[:-1])
    freq = 0.5 / np.diff(crossings)
    expected = f0 + (f1 - f0) * mid / duration
    assert np.max(np.abs(freq / expected - 1.0)) < 0.01
    assert freq[-1] > 0.95 * f1  # reaches the end frequency
    assert np.max(np.abs(x)) <= 0.05


def test_step_ramp_sine_closed_forms():
    t = signals.time_grid(1.0, 1000.0)
    step = signals.command(StepCommand(kind="step", amplitude=0.02, time=0.1, offset=0.01), t, 1.0)
    assert np.all(step[t < 0.1] == 0.01) and np.all(step[t >= 0.1] == pytest.approx(0.03))
    ramp = signals.command(RampCommand(kind="ramp", rate=0.2, time=0.5), t, 1.0)
    assert np.allclose(ramp, 0.2 * np.maximum(t - 0.5, 0.0))
    sine = signals.command(SineCommand(kind="sine", amplitude=0.03, frequency=2.0), t, 1.0)
    assert np.allclose(sine, 0.03 * np.sin(4 * np.pi * t))


def test_loads():
    t = signals.time_grid(0.1, 1000.0)
    assert signals.load(NoLoad(kind="none"), t)[0].sum() == 0.0
    torque, k = signals.load(ConstantLoad(kind="constant", torque=-150.0), t)
    assert np.all(torque == -150.0) and k == 0.0
    torque, k = signals.load(SpringLoad(kind="spring", torque=10.0, stiffness=2000.0), t)
    assert np.all(torque == 10.0) and k == 2000.0
