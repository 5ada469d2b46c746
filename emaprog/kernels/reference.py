"""Reference Model time loop: controller (ZOH) + current regulator (hysteresis H-bridge or
PWM inverter with a PI loop) + BLDC + 2-DOF mechanics."""

from __future__ import annotations

import numpy as np
from numba import njit

from .bldc import (
    IDLE_PHASE,
    NEGATIVE_PHASE,
    PHASE_OFFSET,
    POSITIVE_PHASE,
    equivalent_current,
    phase_coefficient,
    sector,
    trapezoid,
    winding_step,
)
from .control import quantize, sample_and_control
from .drive import (
    EDGE_TOLERANCE,
    L_APPLIED,
    L_CLOCK,
    LOOP_SLOTS,
    PWM,
    leg_level,
    loop_sample,
    next_edge,
    positive_duty,
)
from .mechanics import mechanics_step
from .sensors import F_CURRENT, advance, analog_step, feedback_inputs, filter_bank
from .structs import ChainState

#: Slots of the energy ledger written by :func:`simulate_reference` [J].
ENERGY_SLOTS = (
    "inverter",
    "copper",
    "friction",
    "viscous",
    "link_damping",
    "load",
    "end_stop",
    "stored_initial",
    "stored_final",
)
(
    E_INVERTER,
    E_COPPER,
    E_FRICTION,
    E_VISCOUS,
    E_LINK_DAMPING,
    E_LOAD,
    E_END_STOP,
    E_STORED_INITIAL,
    E_STORED_FINAL,
) = range(len(ENERGY_SLOTS))

#: Slots of the state carried from one call of :func:`simulate_reference` to the next,
#: so that a long run can be done in chunks (progress bar) with the same numbers.
STATE_SLOTS = (
    "current_a",
    "current_b",
    "current_c",
    "motor_angle",
    "motor_speed",
    "surface_angle",
    "surface_speed",
    "position_integral",
    "speed_integral",
    "bridge",
    "mean_current",
    "mean_current_a",
    "mean_current_b",
    "mean_current_c",
    "mean_torque",
) + tuple(f"loop_{slot}" for slot in LOOP_SLOTS)
#: The sensor chain's states (:mod:`emaprog.kernels.sensors`): its
#: :class:`~emaprog.kernels.structs.ChainState`, then each phase-current line's filter.
STATE_SLOTS += tuple(f"chain_{field}" for field in ChainState._fields)
STATE_SLOTS += tuple(f"line_{phase}_{j}" for phase in "abc" for j in range(2))
(
    S_CURRENT_A,
    S_CURRENT_B,
    S_CURRENT_C,
    S_MOTOR_ANGLE,
    S_MOTOR_SPEED,
    S_SURFACE_ANGLE,
    S_SURFACE_SPEED,
    S_POSITION_INTEGRAL,
    S_SPEED_INTEGRAL,
    S_BRIDGE,
    S_MEAN_CURRENT,
    S_MEAN_CURRENT_A,
    S_MEAN_CURRENT_B,
    S_MEAN_CURRENT_C,
    S_MEAN_TORQUE,
    S_LOOP,
) = range(STATE_SLOTS.index("loop_clock") + 1)
S_CHAIN = S_LOOP + len(LOOP_SLOTS)
S_LINES = S_CHAIN + len(ChainState._fields)


def initial_state() -> np.ndarray:
    """The state at rest (all zeros; the bridge starts driving positive current; a PWM
    period starts with the first step: its clock past any period)."""
    state = np.zeros(len(STATE_SLOTS))
    state[S_BRIDGE] = 1.0
    state[S_LOOP + L_CLOCK] = np.inf
    return state


@njit(cache=True)
def _stored_energy(i, l, theta_m, omega_m, theta_s, omega_s, backlash, mech):
    """Magnetic + kinetic + elastic energy [J] (link spring outside the dead band, stops)."""
    magnetic = 0.5 * (l[0] * i[0] ** 2 + l[1] * i[1] ** 2 + l[2] * i[2] ** 2)
    kinetic = 0.5 * mech.motor_inertia * omega_m**2 + 0.5 * mech.surface_inertia * omega_s**2
    twist = abs(theta_m / mech.gear_ratio - theta_s) - 0.5 * backlash
    elastic = 0.5 * mech.transmission_stiffness * twist**2 if twist > 0.0 else 0.0
    return magnetic + kinetic + elastic


@njit(cache=True)
def _sample_currents(k, acc_eq, acc_a, acc_b, acc_c, acc_t, noise, sens, out):
    """Write period k's integrate-and-dump currents (line noise, ADC) and torque into ``out``."""
    out.current[k] = quantize(acc_eq + noise.current[k], sens.current_lsb, sens.current_range)
    out.current_a[k] = quantize(acc_a + noise.current_a[k], sens.current_lsb, sens.current_range)
    out.current_b[k] = quantize(acc_b + noise.current_b[k], sens.current_lsb, sens.current_range)
    out.current_c[k] = quantize(acc_c + noise.current_c[k], sens.current_lsb, sens.current_range)
    out.torque[k] = acc_t


@njit(cache=True)
def _pwm_substep(i, scratch, e, r, l, s6, current_ref, speed, loop, elec, dt):
    """One integration step under the PWM inverter, split at every switching edge and PWM
    period start inside it (:mod:`emaprog.kernels.drive`); ``i`` and ``loop`` in place,
    ``scratch`` the (legs, v, tied) arrays of :func:`winding_step`. Returns the inverter's
    energy over the step [J]."""
    period, dead, vdc = elec.pwm_period, elec.dead_time, elec.dc_bus_voltage
    legs, v, tied = scratch
    p, q, idle = POSITIVE_PHASE[s6], NEGATIVE_PHASE[s6], IDLE_PHASE[s6]
    remaining = dt
    work = 0.0
    legs[idle] = 0
    while remaining > 0.0:
        if loop[L_CLOCK] >= period - EDGE_TOLERANCE:
            loop[L_CLOCK] = 0.0
            loop_sample(loop, 0.5 * (i[p] - i[q]), current_ref, speed, elec)
        clock = loop[L_CLOCK]
        duty = positive_duty(loop[L_APPLIED], vdc)
        edge = min(next_edge(clock, duty, period, dead), next_edge(clock, 1.0 - duty, period, dead))
        h = min(edge - clock, remaining)
        middle = clock + 0.5 * h
        legs[p] = leg_level(middle, duty, period, dead)
        legs[q] = leg_level(middle, 1.0 - duty, period, dead)
        work += winding_step(i, legs, e, r, l, vdc, h, v, tied) * h
        loop[L_CLOCK] = clock + h
        remaining -= h
    return work


@njit(cache=True)
def simulate_reference(drive, noise, plant, faults, substeps, out, energy, state, start, stop):
    """Run the Reference Model over controller periods ``start`` to ``stop - 1``.

    Parameters
    ----------
    drive : Drive
        Command [rad], hinge moment [N m] per period, aerodynamic spring [N m/rad], the
        rotor's electrical angle at the first sample [rad] (the motor angle output starts
        at 0 there: a position sensor whose zero is not the rotor's electrical zero).
    noise : SensorNoise
        Electrical noise on the feedback and current lines (drawn outside).
    plant : Plant
        Parameter structs (:mod:`emaprog.kernels.structs`).
    faults : FaultParams
        Physical fault magnitudes (eccentricity as zeta).
    substeps : int
        Integration steps per controller period (time step = period / substeps).
    out : ReferenceOutputs
        Row k holds the feedback sampled at ``k T`` and the currents/torque
        averaged over the period ending at ``k T`` (integrate-and-dump ADC).
    energy : (9,) float64, in/out
        Energy ledger [J], slots :data:`ENERGY_SLOTS`; reset when ``start`` is 0,
        accumulated over later chunks.
    state : float64 array of :data:`STATE_SLOTS`, in/out
        Slots :data:`STATE_SLOTS`; :func:`initial_state` for ``start`` 0, then
        whatever the previous chunk left. Chunked and single-call runs are identical.
    start, stop : int
        Rows to compute (``0 <= start <= stop <= command.size``).
    """
    elec, mech = plant.electrical, plant.mechanical
    dt = plant.controller.period / substeps
    pp = elec.pole_pairs
    working = np.array([1.0 - faults.short_a, 1.0 - faults.short_b, 1.0 - faults.short_c])
    r = working * elec.phase_resistance
    l = working * working * elec.phase_inductance
    i = np.array([state[S_CURRENT_A], state[S_CURRENT_B], state[S_CURRENT_C]])
    e = np.zeros(3)
    legs = np.zeros(3, dtype=np.int64)
    v_scratch = np.zeros(3)
    tied_scratch = np.zeros(3, dtype=np.int64)
    scratch = (legs, v_scratch, tied_scratch)
    theta_m = state[S_MOTOR_ANGLE]
    omega_m = state[S_MOTOR_SPEED]
    theta_s = state[S_SURFACE_ANGLE]
    omega_s = state[S_SURFACE_SPEED]
    position_int = state[S_POSITION_INTEGRAL]
    speed_int = state[S_SPEED_INTEGRAL]
    bridge = int(state[S_BRIDGE])
    acc_eq = state[S_MEAN_CURRENT]
    acc_a = state[S_MEAN_CURRENT_A]
    acc_b = state[S_MEAN_CURRENT_B]
    acc_c = state[S_MEAN_CURRENT_C]
    acc_t = state[S_MEAN_TORQUE]
    loop = state[S_LOOP:S_CHAIN]
    pwm = elec.regulator == PWM
    sens = plant.sensors
    bank = filter_bank(sens, dt, plant.controller.period)
    chain = ChainState(
        state[S_CHAIN],
        state[S_CHAIN + 1],
        state[S_CHAIN + 2],
        state[S_CHAIN + 3],
        state[S_CHAIN + 4],
        state[S_CHAIN + 5],
        state[S_CHAIN + 6],
    )
    a0, a1 = state[S_LINES], state[S_LINES + 1]
    b0, b1 = state[S_LINES + 2], state[S_LINES + 3]
    c0, c1 = state[S_LINES + 4], state[S_LINES + 5]
    point = sens.current_point
    if start == 0:
        for slot in range(energy.size):
            energy[slot] = 0.0
        energy[E_STORED_INITIAL] = _stored_energy(
            i, l, theta_m, omega_m, theta_s, omega_s, faults.backlash, mech
        )
    for k in range(start, stop):
        position_in, speed_in, chain = feedback_inputs(
            chain, theta_s, theta_m, omega_m, sens, bank, plant.controller.period
        )
        pos_meas, spd_meas, current_ref, position_int, speed_int = sample_and_control(
            drive.command[k],
            position_in,
            speed_in,
            noise.position[k],
            noise.speed[k],
            position_int,
            speed_int,
            plant,
        )
        out.position[k] = pos_meas
        out.speed[k] = spd_meas
        out.motor_angle[k] = theta_m
        _sample_currents(k, acc_eq, acc_a, acc_b, acc_c, acc_t, noise, plant.sensors, out)
        load = drive.load_torque[k] + drive.load_offset
        acc_eq = 0.0
        acc_a = 0.0
        acc_b = 0.0
        acc_c = 0.0
        acc_t = 0.0
        for _ in range(substeps):
            theta_e = pp * theta_m + drive.electrical_angle
            s6 = sector(theta_e)
            p = POSITIVE_PHASE[s6]
            q = NEGATIVE_PHASE[s6]
            if not pwm:
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
                kx = phase_coefficient(
                    theta_e,
                    working[x],
                    faults.eccentricity_zeta,
                    faults.eccentricity_phase,
                    x,
                    elec.back_emf_constant,
                )
                shape = kx * trapezoid(theta_e + PHASE_OFFSET[x])
                e[x] = shape * omega_m
                torque += shape * i[x]
            copper = r[0] * i[0] ** 2 + r[1] * i[1] ** 2 + r[2] * i[2] ** 2
            if pwm:
                work = _pwm_substep(i, scratch, e, r, l, s6, current_ref, spd_meas, loop, elec, dt)
            else:
                work = (
                    winding_step(i, legs, e, r, l, elec.dc_bus_voltage, dt, v_scratch, tied_scratch)
                    * dt
                )
            omega_m_old = omega_m
            omega_s_old = omega_s
            chain = analog_step(chain, theta_s, omega_m, bank)
            theta_m, omega_m, theta_s, omega_s, applied = mechanics_step(
                theta_m,
                omega_m,
                theta_s,
                omega_s,
                torque,
                load,
                drive.load_stiffness,
                faults.friction,
                faults.backlash,
                mech,
                dt,
            )
            energy[E_INVERTER] += work
            energy[E_COPPER] += copper * dt
            energy[E_FRICTION] -= applied.friction * omega_m * dt
            energy[E_VISCOUS] += (
                mech.motor_viscous * omega_m_old * omega_m
                + mech.surface_damping * omega_s_old * omega_s
            ) * dt
            if applied.link != 0.0:
                energy[E_LINK_DAMPING] += (
                    (applied.link - applied.spring) * (omega_m / mech.gear_ratio - omega_s) * dt
                )
            energy[E_LOAD] += applied.hinge * omega_s * dt
            energy[E_END_STOP] -= applied.end_stop * omega_s * dt
            a0, a1 = advance(a0, a1, i[0], bank[F_CURRENT])
            b0, b1 = advance(b0, b1, i[1], bank[F_CURRENT])
            c0, c1 = advance(c0, c1, i[2], bank[F_CURRENT])
            line_a = sens.current_gain_a * a0 + sens.current_offset_a
            line_b = sens.current_gain_b * b0 + sens.current_offset_b
            line_c = sens.current_gain_c * c0 + sens.current_offset_c
            if point:
                acc_eq = equivalent_current(line_a, line_b, line_c, torque)
                acc_a, acc_b, acc_c, acc_t = line_a, line_b, line_c, torque
            else:
                acc_eq += equivalent_current(line_a, line_b, line_c, torque)
                acc_a += line_a
                acc_b += line_b
                acc_c += line_c
                acc_t += torque
        if not point:
            acc_eq /= substeps
            acc_a /= substeps
            acc_b /= substeps
            acc_c /= substeps
            acc_t /= substeps
    energy[E_STORED_FINAL] = _stored_energy(
        i, l, theta_m, omega_m, theta_s, omega_s, faults.backlash, mech
    )
    for slot, value in (
        (S_CURRENT_A, i[0]),
        (S_CURRENT_B, i[1]),
        (S_CURRENT_C, i[2]),
        (S_MOTOR_ANGLE, theta_m),
        (S_MOTOR_SPEED, omega_m),
        (S_SURFACE_ANGLE, theta_s),
        (S_SURFACE_SPEED, omega_s),
        (S_POSITION_INTEGRAL, position_int),
        (S_SPEED_INTEGRAL, speed_int),
        (S_BRIDGE, float(bridge)),
        (S_MEAN_CURRENT, acc_eq),
        (S_MEAN_CURRENT_A, acc_a),
        (S_MEAN_CURRENT_B, acc_b),
        (S_MEAN_CURRENT_C, acc_c),
        (S_MEAN_TORQUE, acc_t),
    ):
        state[slot] = value
    for j, value in enumerate(chain):
        state[S_CHAIN + j] = value
    for j, value in enumerate((a0, a1, b0, b1, c0, c1)):
        state[S_LINES + j] = value
