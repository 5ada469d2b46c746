"""2-DOF transmission: Borello dry friction, compliant link with backlash, end stops.

Motor side (inertia ``J_m``, angle ``theta_m``) drives the surface (``J_s``,
``theta_s``) through the gear ratio ``N`` and a spring-damper at the output
with a dead band of total width ``backlash``. Dry friction acts at the motor
(Borello model); aerodynamic load and end stops act at the surface.

Integration is semi-implicit (symplectic) Euler: velocities first, then
angles with the new velocities; stable for the stiff link at the Monitor step.
"""

from __future__ import annotations

from typing import NamedTuple

from numba import njit


class TransmissionTorques(NamedTuple):
    """The torques one :func:`mechanics_step` applied [N m] (for energy accounting)."""

    link: float  # transmitted at the output by the compliant link (spring + damper)
    spring: float  # the link's elastic part
    friction: float  # dry friction at the motor (Borello)
    hinge: float  # aerodynamic hinge moment on the surface, opposing +deflection
    end_stop: float  # contact torque of the end stops on the surface


@njit(cache=True)
def link_torque(theta_m, omega_m, theta_s, omega_s, backlash, mech):
    """Torque transmitted at the output by the compliant link with dead band [N m].

    ``twist = theta_m / N - theta_s``. Inside the play (``|twist| <= b/2``) no
    torque is transmitted; in contact, ``K (twist -+ b/2) + C d(twist)/dt``,
    clipped so the contact only pushes (no adhesive pull on separation).
    Returns (link torque, its spring part ``K (twist -+ b/2)``).
    """
    inv_n = 1.0 / mech.gear_ratio  # a constant: the division leaves the time loop
    twist = theta_m * inv_n - theta_s
    rate = omega_m * inv_n - omega_s
    half = 0.5 * backlash
    if twist > half:
        spring = mech.transmission_stiffness * (twist - half)
        return max(spring + mech.transmission_damping * rate, 0.0), spring
    if twist < -half:
        spring = mech.transmission_stiffness * (twist + half)
        return min(spring + mech.transmission_damping * rate, 0.0), spring
    return 0.0, 0.0


@njit(cache=True)
def end_stop_torque(theta_s, omega_s, mech):
    """Contact torque of the symmetric end stops on the surface [N m] (push only)."""
    if theta_s > mech.end_stop:
        return min(
            -mech.end_stop_stiffness * (theta_s - mech.end_stop) - mech.end_stop_damping * omega_s,
            0.0,
        )
    if theta_s < -mech.end_stop:
        return max(
            -mech.end_stop_stiffness * (theta_s + mech.end_stop) - mech.end_stop_damping * omega_s,
            0.0,
        )
    return 0.0


@njit(cache=True)
def borello_velocity(omega, active, static, dynamic, inertia, dt):
    """One step of the Borello dry-friction model; returns (new velocity, friction torque).

    Parameters
    ----------
    omega : float
        Velocity at the start of the step [rad/s]; exactly 0 means stuck.
    active : float
        Sum of all torques but dry friction [N m].
    static, dynamic : float
        Breakaway and sliding friction torques [N m], ``static >= dynamic``.
    inertia : float
        [kg m^2]. dt : float, step [s].

    Notes
    -----
    Borello & Dalla Vedova's discrete model: a stuck body stays stuck while
    ``|active| <= static`` (friction balances it); beyond, it breaks away and
    slides against ``dynamic`` friction; a sliding body that would reverse its
    velocity within the step is stopped (velocity set to exactly 0).
    """
    if omega == 0.0:
        if abs(active) <= static:
            return 0.0, -active
        friction = -dynamic if active > 0.0 else dynamic
        return (active + friction) * (dt / inertia), friction
    friction = -dynamic if omega > 0.0 else dynamic
    new = omega + (active + friction) * (dt / inertia)
    if new * omega < 0.0:
        return 0.0, friction
    return new, friction


@njit(cache=True)
def mechanics_step(
    theta_m,
    omega_m,
    theta_s,
    omega_s,
    motor_torque,
    load_torque,
    load_stiffness,
    friction_scale,
    backlash,
    mech,
    dt,
):
    """Advance the 2-DOF transmission by ``dt``.

    Parameters
    ----------
    motor_torque : float
        Electromagnetic torque [N m].
    load_torque, load_stiffness : float
        Hinge moment ``load_torque + load_stiffness * theta_s`` opposing +deflection
        [N m], [N m/rad].
    friction_scale : float
        Dry-friction multiplier (fault ``k_f``) [-]. backlash : float [rad].

    Returns
    -------
    theta_m, omega_m, theta_s, omega_s, torques
        New state and the :class:`TransmissionTorques` applied in the step.
    """
    link, spring = link_torque(theta_m, omega_m, theta_s, omega_s, backlash, mech)
    active_m = motor_torque - mech.motor_viscous * omega_m - link * (1.0 / mech.gear_ratio)
    new_omega_m, friction = borello_velocity(
        omega_m,
        active_m,
        friction_scale * mech.static_friction,
        friction_scale * mech.dynamic_friction,
        mech.motor_inertia,
        dt,
    )
    hinge = load_torque + load_stiffness * theta_s
    stop = end_stop_torque(theta_s, omega_s, mech)
    active_s = link - mech.surface_damping * omega_s - hinge + stop
    new_omega_s = omega_s + active_s * (dt / mech.surface_inertia)
    return (
        theta_m + new_omega_m * dt,
        new_omega_m,
        theta_s + new_omega_s * dt,
        new_omega_s,
        TransmissionTorques(link, spring, friction, hinge, stop),
    )
