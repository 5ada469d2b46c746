"""Reference Model time loop: controller (ZOH) + hysteresis H-bridge + BLDC + 2-DOF mechanics."""

from __future__ import annotations

import numpy as np
from numba import njit

from .bldc import (
    IDLE_PHASE, NEGATIVE_PHASE, POSITIVE_PHASE, PHASE_OFFSET, equivalent_current,
    phase_coefficient, sector, trapezoid, winding_step,
)
from .control import controller_update, quantize
from .mechanics import end_stop_torque, mechanics_step

#: Slots of the energy ledger written by :func:`simulate_reference` [J].
ENERGY_SLOTS = ("inverter", "copper", "friction", "viscous", "link_damping", "load",
                "end_stop", "stored_initial", "stored_final")

#: Slots of the state carried from one call of :func:`simulate_reference` to the next,
#: so that a long run can be done in chunks (progress bar) with the same numbers.
STATE_SLOTS = ("current_a", "current_b", "current_c", "motor_angle", "motor_speed",
               "surface_angle", "surface_speed", "position_integral", "speed_integral",
               "bridge", "mean_current", "mean_current_a", "mean_current_b", "mean_current_c",
               "mean_torque")
_I0, _I1, _I2, _THETA_M, _OMEGA_M, _THETA_S, _OMEGA_S, _POS_INT, _SPD_INT, _BRIDGE, \
    _ACC_EQ, _ACC_A, _ACC_B, _ACC_C, _ACC_T = range(len(STATE_SLOTS))


def initial_state() -> np.ndarray:
    """The state at rest (all zeros; the bridge starts driving positive current)."""
    state = np.zeros(len(STATE_SLOTS))
    state[_BRIDGE] = 1.0
    return state


@njit(cache=True)
def _stored_energy(i, l, theta_m, omega_m, theta_s, omega_s, backlash, mech):
    """Magnetic + kinetic + elastic energy [J] (link spring outside the dead band, stops)."""
    magnetic = 0.5 * (l[0] * i[0] ** 2 + l[1] * i[1] ** 2 + l[2] * i[2] ** 2)
    kinetic = 0.5 * mech.motor_inertia * omega_m ** 2 + 0.5 * mech.surface_inertia * omega_s ** 2
    twist = abs(theta_m / mech.gear_ratio - theta_s) - 0.5 * backlash
    elastic = 0.5 * mech.transmission_stiffness * twist ** 2 if twist > 0.0 else 0.0
    return magnetic + kinetic + elastic


@njit(cache=True)
def simulate_reference(command, load_torque, load_stiffness, noise_position, noise_speed,
                       noise_current, elec, mech, ctrl, sens, faults, substeps,
                       position, speed, current, current_a, current_b, current_c,
                       torque_out, motor_angle, energy, state, start, stop):
    """Run the Reference Model over controller periods ``start`` to ``stop - 1``.

    Parameters
    ----------
    command, load_torque : (n,) float64
        Surface position command [rad] and hinge-moment offset [N m] per period.
    load_stiffness : float
        Aerodynamic spring [N m/rad].
    noise_position, noise_speed : (n,) float64
        Electrical noise on the feedback lines [rad], [rad/s] (drawn outside).
    noise_current : (n, 4) float64
        Noise on the recorded equivalent and phase currents [A].
    elec, mech, ctrl, sens : NamedTuple
        Parameter structs (:mod:`emaprog.parameters`).
    faults : FaultParams
        ``ecc_magnitude`` is the eccentricity zeta [-].
    substeps : int
        Integration steps per controller period (time step = period / substeps).
    position ... motor_angle : (n,) float64, outputs
        Row k holds the feedback sampled at ``k T`` and the currents/torque
        averaged over the period ending at ``k T`` (integrate-and-dump ADC).
    energy : (9,) float64, in/out
        Energy ledger [J], slots :data:`ENERGY_SLOTS`; reset when ``start`` is 0,
        accumulated over later chunks.
    state : (15,) float64, in/out
        Slots :data:`STATE_SLOTS`; :func:`initial_state` for ``start`` 0, then
        whatever the previous chunk left. Chunked and single-call runs are identical.
    start, stop : int
        Rows to compute (``0 <= start <= stop <= command.size``).
    """
    dt = ctrl.period / substeps
    pp = elec.pole_pairs
    working = np.array([1.0 - faults.short_a, 1.0 - faults.short_b, 1.0 - faults.short_c])
    r = working * elec.phase_resistance
    l = working * working * elec.phase_inductance
    i = np.array([state[_I0], state[_I1], state[_I2]])
    e = np.zeros(3)
    legs = np.zeros(3, dtype=np.int64)
    v_scratch = np.zeros(3)
    tied_scratch = np.zeros(3, dtype=np.int64)
    theta_m = state[_THETA_M]
    omega_m = state[_OMEGA_M]
    theta_s = state[_THETA_S]
    omega_s = state[_OMEGA_S]
    position_int = state[_POS_INT]
    speed_int = state[_SPD_INT]
    bridge = int(state[_BRIDGE])
    acc_eq = state[_ACC_EQ]
    acc_a = state[_ACC_A]
    acc_b = state[_ACC_B]
    acc_c = state[_ACC_C]
    acc_t = state[_ACC_T]
    if start == 0:
        for slot in range(energy.size):
            energy[slot] = 0.0
        energy[7] = _stored_energy(i, l, theta_m, omega_m, theta_s, omega_s, faults.backlash, mech)
    for k in range(start, stop):
        pos_meas = quantize(theta_s + sens.position_offset + noise_position[k],
                            sens.position_lsb, sens.position_range)
        spd_meas = quantize(omega_m + noise_speed[k], sens.speed_lsb, sens.speed_range)
        position[k] = pos_meas
        speed[k] = spd_meas
        motor_angle[k] = theta_m
        current[k] = quantize(acc_eq + noise_current[k, 0], sens.current_lsb, sens.current_range)
        current_a[k] = quantize(acc_a + noise_current[k, 1], sens.current_lsb, sens.current_range)
        current_b[k] = quantize(acc_b + noise_current[k, 2], sens.current_lsb, sens.current_range)
        current_c[k] = quantize(acc_c + noise_current[k, 3], sens.current_lsb, sens.current_range)
        torque_out[k] = acc_t
        current_ref, position_int, speed_int = controller_update(
            command[k], pos_meas, spd_meas, position_int, speed_int, ctrl)
        acc_eq = 0.0
        acc_a = 0.0
        acc_b = 0.0
        acc_c = 0.0
        acc_t = 0.0
        for _ in range(substeps):
            theta_e = pp * theta_m
            s6 = sector(theta_e)
            p = POSITIVE_PHASE[s6]
            q = NEGATIVE_PHASE[s6]
            # hysteresis regulator on the active pair's current
            regulated = 0.5 * (i[p] - i[q])
            if regulated < current_ref - elec.hysteresis_band:
                bridge = 1
            elif regulated > current_ref + elec.hysteresis_band:
                bridge = -1
            legs[p] = bridge
            legs[q] = -bridge
            legs[IDLE_PHASE[s6]] = 0
            torque = 0.0
            for x in range(3):
                kx = phase_coefficient(theta_e, working[x], faults.ecc_magnitude,
                                       faults.ecc_phase, x, elec.back_emf_constant)
                shape = kx * trapezoid(theta_e + PHASE_OFFSET[x])
                e[x] = shape * omega_m
                torque += shape * i[x]
            copper = r[0] * i[0] ** 2 + r[1] * i[1] ** 2 + r[2] * i[2] ** 2
            power = winding_step(i, legs, e, r, l, elec.dc_bus_voltage, dt, v_scratch, tied_scratch)
            omega_m_old = omega_m
            omega_s_old = omega_s
            spring = _spring_part(theta_m, theta_s, faults.backlash, mech)
            hinge = load_torque[k] + load_stiffness * theta_s
            stop = end_stop_torque(theta_s, omega_s, mech)
            theta_m, omega_m, theta_s, omega_s, link, friction = mechanics_step(
                theta_m, omega_m, theta_s, omega_s, torque, load_torque[k], load_stiffness,
                faults.friction, faults.backlash, mech, dt)
            energy[0] += power * dt
            energy[1] += copper * dt
            energy[2] -= friction * omega_m * dt
            energy[3] += (mech.motor_viscous * omega_m_old * omega_m
                          + mech.surface_damping * omega_s_old * omega_s) * dt
            if link != 0.0:
                energy[4] += (link - spring) * (omega_m / mech.gear_ratio - omega_s) * dt
            energy[5] += hinge * omega_s * dt
            energy[6] -= stop * omega_s * dt
            acc_eq += equivalent_current(i[0], i[1], i[2], torque)
            acc_a += i[0]
            acc_b += i[1]
            acc_c += i[2]
            acc_t += torque
        acc_eq /= substeps
        acc_a /= substeps
        acc_b /= substeps
        acc_c /= substeps
        acc_t /= substeps
    energy[8] = _stored_energy(i, l, theta_m, omega_m, theta_s, omega_s, faults.backlash, mech)
    state[_I0] = i[0]
    state[_I1] = i[1]
    state[_I2] = i[2]
    state[_THETA_M] = theta_m
    state[_OMEGA_M] = omega_m
    state[_THETA_S] = theta_s
    state[_OMEGA_S] = omega_s
    state[_POS_INT] = position_int
    state[_SPD_INT] = speed_int
    state[_BRIDGE] = bridge
    state[_ACC_EQ] = acc_eq
    state[_ACC_A] = acc_a
    state[_ACC_B] = acc_b
    state[_ACC_C] = acc_c
    state[_ACC_T] = acc_t


@njit(cache=True)
def _spring_part(theta_m, theta_s, backlash, mech):
    twist = theta_m / mech.gear_ratio - theta_s
    half = 0.5 * backlash
    if twist > half:
        return mech.transmission_stiffness * (twist - half)
    if twist < -half:
        return mech.transmission_stiffness * (twist + half)
    return 0.0
