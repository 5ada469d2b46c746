"""The drive's current regulator: a PWM voltage inverter with a PI current loop.

The hysteresis regulator (the paper's) lives in the Reference kernel's time loop; this
module is the other form a real drive takes (docs/reference.md, Parameter-set YAML,
``drive``), shared by both models:

* **PI loop on the active pair.** Once a PWM period, at the carrier's valley (where a
  centre-aligned PWM current equals its period mean), the drive samples the pair current
  ``y = (i_p - i_q)/2`` and sets the pair's voltage demand
  ``u = K_p (I_ref - y) + integral + G_ff w``, clipped to +/-Vdc, with conditional
  integration (anti-windup). ``G_ff w`` is the back-EMF feed-forward on the speed the
  controller measured. The demand is applied ``computation_delay`` periods later.
* **Complementary legs with dead time.** The positive leg's duty is
  ``d = 1/2 + u/(2 Vdc)``, the negative leg's ``1 - d`` (mean pair voltage ``u``); at each
  transition both switches of a leg are off for the dead time, and the terminal follows
  the freewheeling diode the current's sign selects. The idle phase's leg stays off.

The Reference switches the legs edge by edge (:func:`next_edge`, :func:`leg_level`); the
Monitor applies the period mean of the demand and the dead time's mean voltage loss
(:func:`dead_time_loss`).
"""

from __future__ import annotations

from numba import njit

from .control import clip
from .structs import REGULATORS

HYSTERESIS = REGULATORS.index("hysteresis")
PWM = REGULATORS.index("pwm")

#: Slots of the loop's state carried between calls: PWM clock [s] within the period,
#: the PI integral [V], the applied demand and the two queued ones [V].
LOOP_SLOTS = ("clock", "integral", "applied", "queued_1", "queued_2")
L_CLOCK, L_INTEGRAL, L_APPLIED, L_QUEUED_1, L_QUEUED_2 = range(len(LOOP_SLOTS))

#: Time under which two switching instants are one [s] (a thousandth of a nanosecond).
EDGE_TOLERANCE = 1e-12


@njit(cache=True)
def loop_sample(loop, pair_current, current_ref, speed, elec):
    """The PI's update at a period's start: writes the new demand into the delay queue of
    ``loop`` (:data:`LOOP_SLOTS`) and returns the demand applied from now on [V]."""
    error = current_ref - pair_current
    raw = elec.loop_gain * error + loop[L_INTEGRAL] + elec.emf_feedforward * speed
    demand = clip(raw, elec.dc_bus_voltage)
    if raw == demand or error * raw < 0.0:
        loop[L_INTEGRAL] += elec.loop_integral * error * elec.pwm_period
    if elec.loop_delay == 0:
        loop[L_APPLIED] = demand
    elif elec.loop_delay == 1:
        loop[L_APPLIED] = loop[L_QUEUED_1]
        loop[L_QUEUED_1] = demand
    else:
        loop[L_APPLIED] = loop[L_QUEUED_1]
        loop[L_QUEUED_1] = loop[L_QUEUED_2]
        loop[L_QUEUED_2] = demand
    return loop[L_APPLIED]


@njit(cache=True)
def positive_duty(demand, vdc):
    """Duty of the positive leg for a mean pair voltage ``demand`` [V] (negative leg: 1 - d)."""
    return min(1.0, max(0.0, 0.5 + 0.5 * demand / vdc))


@njit(cache=True)
def leg_level(t, duty, period, dead):
    """A leg's switches at time ``t`` in the period (centre-aligned carrier): +1 upper on,
    -1 lower on, 0 both off (the dead time after the lower switch opens or the upper one)."""
    rise = 0.5 * period * (1.0 - duty)
    fall = 0.5 * period * (1.0 + duty)
    if rise + dead <= t < fall:
        return 1
    if t < rise or t >= fall + dead:
        return -1
    return 0


@njit(cache=True)
def next_edge(t, duty, period, dead):
    """The first switching instant of a leg after ``t`` in the period, or the period's end."""
    rise = 0.5 * period * (1.0 - duty)
    fall = 0.5 * period * (1.0 + duty)
    for edge in (rise, rise + dead, fall, fall + dead):
        if edge > t + EDGE_TOLERANCE and edge < period:
            return edge
    return period


@njit(cache=True)
def dead_time_loss(pair_current, inductance, elec):
    """The dead time's mean loss of pair voltage over a period [V]: each leg's terminal
    follows its diode for ``dead_time`` at each of its two edges, ``2 Vdc t_d / T`` on the
    pair against the current; linear within the switching ripple (the current crosses zero
    inside the period there), taken as ``Vdc T / (4 L_pair)``: the two-level ripple at half
    duty, an upper bound of the three-level ripple these complementary legs make."""
    full = 2.0 * elec.dc_bus_voltage * elec.dead_time / elec.pwm_period
    ripple = elec.dc_bus_voltage * elec.pwm_period / (4.0 * inductance)
    return full * clip(pair_current / ripple, 1.0)
