"""Three-phase trapezoidal BLDC motor, six-step commutation, ideal H-bridge.

Angle conventions (shared with the Monitor Model, see ``monitor.py``):

* electrical angle ``theta_e = P theta_m``;
* phase shapes ``e_x = k_x trap(theta_e + beta_x) omega_m`` with
  ``beta = (0, +2 pi/3, -2 pi/3)`` for A, B, C, where ``trap`` is the
  odd, 2 pi-periodic trapezoid with a 120 deg flat top centred on pi/2;
* commutation sector ``s6 = floor((theta_e + pi/6) / (pi/3)) mod 6``. With these
  offsets the phase left idle is A in sectors 0 and 3, B in 1 and 4, C in 2 and 5,
  which is exactly the paper's Eq. 4 numbering ``s6 mod 3``
  (0: B,C active; 1: C,A; 2: A,B).

Fault laws (docs/reference.md, The models), per phase ``x``:

* phase short circuit, working fraction ``N_x = 1 - shorted_x``:
  ``R_x = N_x R``, ``L_x = N_x^2 L``, ``k_x proportional to N_x``;
* rotor static eccentricity ``zeta`` at angle ``phi``: the first-order gap
  permeance seen by each phase's winding axis modulates its coefficient,
  ``k_x = N_x k (1 + zeta cos(theta_e + phi + beta_x))``.
  Reason for this law: a reduced gap raises the flux linked by the coils
  facing it and a widened gap lowers it, to first order in ``zeta``; expressed
  on each phase's own electrical axis the modulation sums to zero over the
  three phases and averages to zero over every electrical revolution, so the
  mean torque, position and speed barely change while the current waveform
  does (the paper's Sec. 3 description). Because it is attached to the phase
  axes, its effect on the active pair is known in closed form, which the
  Monitor's ``pair`` shape function reproduces exactly.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

PHASE_OFFSET = np.array([0.0, 2.0 * math.pi / 3.0, -2.0 * math.pi / 3.0])
#: Active pair per six-step sector: the phase driven positive and the one driven negative.
POSITIVE_PHASE = np.array([1, 0, 0, 2, 2, 1])
NEGATIVE_PHASE = np.array([2, 2, 1, 1, 0, 0])
IDLE_PHASE = np.array([0, 1, 2, 0, 1, 2])
SIXTH = math.pi / 3.0
TWO_PI = 2.0 * math.pi
# Angles are wrapped with floor() of a product, not Python's float %: numba's % is fmod plus a
# sign fix, whose cost grows with the angle (tens of ns a call at the thousands of rad of a
# long run), and both models wrap the angle every step.
INV_SIXTH = 3.0 / math.pi
INV_TWO_PI = 0.5 / math.pi


@njit(cache=True)
def trapezoid(theta_e):
    """Unit trapezoidal back-EMF shape, 120 deg flat top centred on pi/2 [-]."""
    x = theta_e - TWO_PI * math.floor(theta_e * INV_TWO_PI)
    if x < math.pi / 6.0:
        return x / (math.pi / 6.0)
    if x < 5.0 * math.pi / 6.0:
        return 1.0
    if x < 7.0 * math.pi / 6.0:
        return (math.pi - x) / (math.pi / 6.0)
    if x < 11.0 * math.pi / 6.0:
        return -1.0
    return (x - TWO_PI) / (math.pi / 6.0)


@njit(cache=True)
def sector(theta_e):
    """Six-step commutation sector 0..5 of the electrical angle (module docstring)."""
    return int(math.floor((theta_e + math.pi / 6.0) * INV_SIXTH)) % 6


@njit(cache=True)
def eccentricity_modulation(theta_e, zeta, phi, phase):
    """Relative change of phase ``phase``'s coefficient, ``zeta cos(theta_e + phi + beta)`` [-]."""
    return zeta * math.cos(theta_e + phi + PHASE_OFFSET[phase])


@njit(cache=True)
def phase_coefficient(theta_e, working, zeta, phi, phase, ke):
    """Back-EMF / torque coefficient of one phase [V s/rad] = [N m/A], faults included."""
    return working * ke * (1.0 + eccentricity_modulation(theta_e, zeta, phi, phase))


@njit(cache=True)
def equivalent_current(ia, ib, ic, torque):
    """``(|Ia| + |Ib| + |Ic|) / 2 * sign(T_M)`` [A] (the paper's footnote 1)."""
    s = 1.0 if torque > 0.0 else (-1.0 if torque < 0.0 else 0.0)
    return 0.5 * (abs(ia) + abs(ib) + abs(ic)) * s


@njit(cache=True)
def _terminal(leg, current, vdc):
    """Terminal voltage of a leg and whether it is tied to a rail (-1 means floating).

    leg +1: upper switch on -> Vdc; leg -1: lower on -> 0. Leg 0 (both off):
    the current freewheels through a diode, the lower one (0 V) while it flows
    into the motor and the upper one (Vdc) while it flows out; with no current
    the terminal floats.
    """
    if leg > 0:
        return vdc, True
    if leg < 0:
        return 0.0, True
    if current > 0.0:
        return 0.0, True
    if current < 0.0:
        return vdc, True
    return 0.0, False


@njit(cache=True)
def star_rates(v, tied, i, e, r, l, vdc):
    """Current derivatives of the star-connected windings; returns (dia, dib, dic, v_n).

    With all three terminals tied, the neutral follows from ``sum di/dt = 0``:
    ``v_n = sum((v_x - R_x i_x - e_x)/L_x) / sum(1/L_x)``. With two tied and one
    floating, the tied pair forms one series loop and the floating terminal sits
    at ``v_n + e_x``; if that leaves [0, Vdc] its diode conducts and the phase is
    tied to that rail (handled by the caller).
    """
    n_tied = tied[0] + tied[1] + tied[2]
    if n_tied == 3:
        num = 0.0
        den = 0.0
        for x in range(3):
            num += (v[x] - r[x] * i[x] - e[x]) / l[x]
            den += 1.0 / l[x]
        vn = num / den
        return (
            (v[0] - vn - r[0] * i[0] - e[0]) / l[0],
            (v[1] - vn - r[1] * i[1] - e[1]) / l[1],
            (v[2] - vn - r[2] * i[2] - e[2]) / l[2],
            vn,
        )
    if n_tied == 2:
        p = 0 if tied[0] else 1
        q = 2 if tied[2] else 1
        di = ((v[p] - v[q]) - (r[p] + r[q]) * i[p] + r[q] * (i[p] + i[q]) - (e[p] - e[q])) / (
            l[p] + l[q]
        )
        vn = v[p] - r[p] * i[p] - l[p] * di - e[p]
        da = di if p == 0 else 0.0
        db = di if p == 1 else (-di if q == 1 else 0.0)
        dc = -di if q == 2 else 0.0
        return da, db, dc, vn
    return 0.0, 0.0, 0.0, 0.5 * vdc


@njit(cache=True)
def winding_step(i, legs, e, r, l, vdc, dt, v, tied):
    """Advance the three phase currents ``i`` (in place) by ``dt`` (explicit Euler).

    ``legs`` are the bridge commands (+1 upper on, -1 lower on, 0 off). Returns
    the inverter output power ``sum v_x i_x`` [W] at the start of the step.
    ``v`` and ``tied`` are scratch arrays of length 3.
    """
    for x in range(3):
        vx, t = _terminal(legs[x], i[x], vdc)
        v[x] = vx
        tied[x] = 1 if t else 0
    dia, dib, dic, vn = star_rates(v, tied, i, e, r, l, vdc)
    # A floating terminal whose potential leaves the rails starts conducting.
    for x in range(3):
        if tied[x] == 0 and tied[0] + tied[1] + tied[2] == 2:
            vx = vn + e[x]
            if vx > vdc or vx < 0.0:
                v[x] = vdc if vx > vdc else 0.0
                tied[x] = 1
                ra, rb, rc, vn2 = star_rates(v, tied, i, e, r, l, vdc)
                rate_x = (ra, rb, rc)[x]
                # the diode admits only the current direction its rail implies
                if (vx > vdc and rate_x < 0.0) or (vx < 0.0 and rate_x > 0.0):
                    dia, dib, dic = ra, rb, rc
                else:
                    tied[x] = 0
    power = v[0] * i[0] + v[1] * i[1] + v[2] * i[2]
    old0, old1, old2 = i[0], i[1], i[2]
    i[0] += dia * dt
    i[1] += dib * dt
    i[2] += dic * dt
    # A freewheeling (leg off) current cannot reverse through its diode: it stops at zero.
    olds = (old0, old1, old2)
    zeroed = False
    for x in range(3):
        if legs[x] == 0 and olds[x] * i[x] <= 0.0 and olds[x] != 0.0:
            i[x] = 0.0
            zeroed = True
        elif legs[x] == 0 and olds[x] == 0.0 and tied[x] == 0:
            i[x] = 0.0
    if zeroed:
        residual = (i[0] + i[1] + i[2]) / 2.0
        for x in range(3):
            if i[x] != 0.0:
                i[x] -= residual
    return power
