"""The sensor chain between the actuator and its logged and fed-back signals, shared by both
models (docs/reference.md, Parameter-set YAML, ``sensors``).

* **Anti-alias filters**, analog, on the position, the tachometer speed and each current
  line: Butterworth low-passes of order 1 or 2 (``*_filter: {cutoff, order}``), integrated
  at each model's own step by the exact discretisation for an input held over the step.
* **Speed from the angle** (``speed_source: angle``): the motor angle as a resolver of
  ``angle_bits`` per revolution reads it, differenced over the controller period, then the
  ``speed_filter`` as a digital filter at the controller rate (the same discretisation at
  the period).
* The controller acts on the filtered signals: the chain is inside the loop, as on the unit.

A filter's state is two numbers (``y`` and ``dy/dt`` for order 2; ``y`` and an unused 0 for
order 1) and its step is ``x' = A_d x + B_d u`` with (A_d, B_d) from :func:`discretise`, held
as the scalars of a :class:`~emaprog.kernels.structs.FilterCoefficients`. The states are
scalars too (a :class:`~emaprog.kernels.structs.ChainState` and a pair per current line),
passed and returned by value: with the states in an array the Monitor's step measured six
times slower (its loop's values no longer stayed in registers).
Every filter is off (cutoff 0) unless the parameter set names it; then nothing changes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .structs import ChainState, FilterCoefficients

#: The filters of the chain, rows of :func:`filter_bank`: the analog ones on the position,
#: speed (tachometer) and current lines, then the digital speed filter.
(F_POSITION, F_SPEED, F_CURRENT, F_DIGITAL_SPEED) = range(4)

BUTTERWORTH_DAMPING = 1.0 / math.sqrt(2.0)


@njit(cache=True)
def discretise(cutoff, order, dt):
    """(A_d (2, 2), B_d (2,)) of a unit-gain Butterworth low-pass of ``cutoff`` [rad/s] and
    ``order`` 1 or 2, exact for an input held over ``dt`` [s] (the augmented matrix
    exponential, Taylor series after scaling, then squaring). Cutoff 0: the identity."""
    a_d = np.eye(2)
    b_d = np.zeros(2)
    if cutoff <= 0.0:
        return a_d, b_d
    m = np.zeros((3, 3))
    if order == 1:
        m[0, 0] = -cutoff
        m[0, 2] = cutoff
    else:
        m[0, 1] = 1.0
        m[1, 0] = -cutoff * cutoff
        m[1, 1] = -2.0 * BUTTERWORTH_DAMPING * cutoff
        m[1, 2] = cutoff * cutoff
    m *= dt
    norm = 0.0
    for r in range(3):
        norm = max(norm, np.sum(np.abs(m[r, :])))
    squarings = max(0, int(math.ceil(math.log2(max(norm, 1e-300)))) + 1)
    m /= 2.0**squarings
    total = np.eye(3)
    term = np.eye(3)
    for j in range(1, 18):
        term = term @ m / j
        total += term
    for _ in range(squarings):
        total = total @ total
    a_d[:, :] = total[:2, :2]
    b_d[:] = total[:2, 2]
    return a_d, b_d


@njit(cache=True)
def coefficients(cutoff, order, dt):
    """One filter's :class:`~emaprog.kernels.structs.FilterCoefficients` (off at cutoff 0)."""
    a_d, b_d = discretise(cutoff, order, dt)
    return FilterCoefficients(
        a_d[0, 0], a_d[0, 1], a_d[1, 0], a_d[1, 1], b_d[0], b_d[1], cutoff > 0.0
    )


@njit(cache=True)
def advance(x0, x1, u, c):
    """One step of a filter in state (x0, x1) under input ``u`` with coefficients ``c``:
    the new state, whose ``x0`` is the output. A filter that is off passes ``u`` through."""
    if not c.on:
        return u, 0.0
    return c.a00 * x0 + c.a01 * x1 + c.b0 * u, c.a10 * x0 + c.a11 * x1 + c.b1 * u


@njit(cache=True)
def filter_bank(sens, dt, period):
    """The chain's filters, a tuple in the order :data:`F_POSITION`...: the analog ones at the
    model's step ``dt`` [s], the digital speed filter at the controller ``period`` [s]."""
    return (
        coefficients(sens.position_cutoff, sens.position_order, dt),
        coefficients(0.0 if sens.speed_from_angle else sens.speed_cutoff, sens.speed_order, dt),
        coefficients(sens.current_cutoff, sens.current_order, dt),
        coefficients(sens.speed_cutoff if sens.speed_from_angle else 0.0, sens.speed_order, period),
    )


@njit(cache=True)
def analog_step(state, theta_s, omega_m, bank):
    """One model step of the position and tachometer filters on the step's starting values;
    returns the new :class:`~emaprog.kernels.structs.ChainState`."""
    p0, p1 = advance(state.position, state.position_rate, theta_s, bank[F_POSITION])
    s0, s1 = advance(state.speed, state.speed_rate, omega_m, bank[F_SPEED])
    return ChainState(p0, p1, s0, s1, state.digital, state.digital_rate, state.resolver)


@njit(cache=True)
def feedback_inputs(state, theta_s, theta_m, omega_m, sens, bank, period):
    """The position [rad] and speed [rad/s] the transducers put on their lines at a controller
    sample (before offset, line noise and ADC), and the new chain state (the resolver's
    reading kept for the next period's difference)."""
    position = state.position if bank[F_POSITION].on else theta_s
    if not sens.speed_from_angle:
        return position, state.speed if bank[F_SPEED].on else omega_m, state
    angle = round(theta_m / sens.angle_lsb) * sens.angle_lsb
    raw = (angle - state.resolver) / period
    d0, d1 = advance(state.digital, state.digital_rate, raw, bank[F_DIGITAL_SPEED])
    new = ChainState(
        state.position, state.position_rate, state.speed, state.speed_rate, d0, d1, angle
    )
    return position, d0, new
