"""Controller electronics: position and speed PI loops with anti-windup, sensors (ADC)."""

from __future__ import annotations

from numba import njit


@njit(cache=True)
def clip(x, limit):
    """Symmetric saturation of ``x`` to ``[-limit, limit]``."""
    if x > limit:
        return limit
    if x < -limit:
        return -limit
    return x


@njit(cache=True)
def quantize(x, lsb, full_scale):
    """ADC: round to the nearest code of width ``lsb``, saturate at +/-full scale."""
    return clip(round(x / lsb) * lsb, full_scale)


@njit(cache=True)
def controller_update(command, position, speed, position_int, speed_int, ctrl):
    """One controller period: returns (I_ref [A], position_int, speed_int).

    Position loop ``w* = sat(Kx e + int)``; speed loop ``I_ref = sat(Kw e_w + int)``.
    Anti-windup by conditional integration: an integrator only moves when its
    loop is not saturated or when the error drives it out of saturation.
    Integrators use forward Euler at the controller period (ZOH output).
    """
    error = command - position
    raw_speed = ctrl.position_gain * error + position_int
    speed_ref = clip(raw_speed, ctrl.speed_limit)
    if raw_speed == speed_ref or error * raw_speed < 0.0:
        position_int += ctrl.position_integral * error * ctrl.period
    speed_error = speed_ref - speed
    raw_current = ctrl.speed_gain * speed_error + speed_int
    current_ref = clip(raw_current, ctrl.current_limit)
    if raw_current == current_ref or speed_error * raw_current < 0.0:
        speed_int += ctrl.speed_integral * speed_error * ctrl.period
    return current_ref, position_int, speed_int


@njit(cache=True)
def sample_and_control(
    command, theta_s, omega_m, noise_position, noise_speed, position_int, speed_int, plant
):
    """One controller period's sampling and control, shared by both models.

    The feedback is sampled at the period's start (position transducer offset,
    line noise [rad], [rad/s], ADC), then the loops run on it (ZOH output).
    Returns (measured position [rad], measured speed [rad/s], I_ref [A],
    position_int, speed_int).
    """
    sens = plant.sensors
    position = quantize(
        theta_s + sens.position_offset + noise_position, sens.position_lsb, sens.position_range
    )
    speed = quantize(omega_m + noise_speed, sens.speed_lsb, sens.speed_range)
    current_ref, position_int, speed_int = controller_update(
        command, position, speed, position_int, speed_int, plant.controller
    )
    return position, speed, current_ref, position_int, speed_int


@njit(cache=True)
def replay_controller(command, position, speed, ctrl, demand):
    """The loops of :func:`controller_update` run on recorded (already measured) signals.

    ``command``, ``position`` [rad], ``speed`` [rad/s] on the controller grid; writes the
    current demand I_ref [A] of each period into ``demand``.
    """
    position_int = 0.0
    speed_int = 0.0
    for k in range(command.size):
        demand[k], position_int, speed_int = controller_update(
            command[k], position[k], speed[k], position_int, speed_int, ctrl
        )
