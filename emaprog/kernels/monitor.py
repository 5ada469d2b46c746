"""Monitor Model: single-phase equivalent BLDC (no PWM) + the shared controller and mechanics.

The equivalent branch is the active phase pair in series: ``R_eq = 2 R``,
``L_eq = 2 L``, torque gain = back-EMF gain ``G = 2 k_e`` (N m/A = V s/rad),
driven by an ideal current regulator whose voltage saturates at +/-Vdc like
the Reference Model's H-bridge. Electrical faults enter through modulating
functions of the rotor angle (docs/reference.md, The models), using the angle conventions and sector
tables of :mod:`emaprog.kernels.bldc`, so both models agree on where each
phase is active.

Commutation transients (``commutation`` on, the shipped default): after each
sector change the phase that left the pair freewheels until its current is
zero (:func:`commutation_step`). This is the one piece of three-phase physics
the single-phase equivalent keeps, because it carries the short circuit's
signature: the outgoing current adds ``|i_out|/2`` to the equivalent current
and decays at a rate set by that phase's ``L_x = N_x^2 L`` and back-EMF, so a
shorted phase commutes faster than the others. Without it the Monitor's PSC
signature errs by 0.25-0.30 against the Reference (the signature error e_sig, docs/reference.md, The models); with it
0.07-0.11, and the healthy Monitor needs no empirical commutation loss.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .bldc import (
    IDLE_PHASE,
    NEGATIVE_PHASE,
    PHASE_OFFSET,
    POSITIVE_PHASE,
    TWO_PI,
    equivalent_current,
    sector,
    trapezoid,
)
from .control import clip, sample_and_control
from .drive import (
    EDGE_TOLERANCE,
    L_APPLIED,
    L_CLOCK,
    LOOP_SLOTS,
    PWM,
    dead_time_loss,
    loop_sample,
    positive_duty,
)
from .mechanics import mechanics_step
from .sensors import F_CURRENT, advance, analog_step, feedback_inputs, filter_bank
from .structs import (
    UNIT_COLUMNS,
    ChainState,
    Drive,
    ElectricalParams,
    ErrorTarget,
    MechanicalParams,
    MonitorFaults,
    MonitorOutputs,
    Plant,
)

(
    U_MOTOR_INERTIA,
    U_SURFACE_INERTIA,
    U_MOTOR_VISCOUS,
    U_STATIC_FRICTION,
    U_DYNAMIC_FRICTION,
    U_PHASE_RESISTANCE,
    U_BACK_EMF_CONSTANT,
    U_PHASE_INDUCTANCE,
    U_TRANSMISSION_STIFFNESS,
    U_HINGE_MOMENT,
    U_HINGE_STIFFNESS,
) = range(len(UNIT_COLUMNS))

SHORT_CIRCUIT_MODULATED = 0
SHORT_CIRCUIT_AVERAGED = 1
ECCENTRICITY_PAIR = 0
ECCENTRICITY_PAPER = 1


@njit(cache=True)
def sector_short_circuit_factors(s6, n_a, n_b, n_c, model):
    """PSC modulating function in commutation sector ``s6``: (gain and resistance, inductance) [-].

    ``model`` SHORT_CIRCUIT_MODULATED (paper Eq. 3-4): mean working fraction of
    the two active phases, ``(N_p + N_q)/2``, and ``(N_p^2 + N_q^2)/2`` for the
    series inductance. SHORT_CIRCUIT_AVERAGED (paper Eq. 1-2): ``N_eq`` and
    ``N_eq^2`` with ``N_eq = (N_A + N_B + N_C)/3``.
    """
    if model == SHORT_CIRCUIT_AVERAGED:
        n_eq = (n_a + n_b + n_c) / 3.0
        return n_eq, n_eq * n_eq
    p = POSITIVE_PHASE[s6]
    q = NEGATIVE_PHASE[s6]
    n_p = n_a if p == 0 else (n_b if p == 1 else n_c)
    n_q = n_a if q == 0 else (n_b if q == 1 else n_c)
    return 0.5 * (n_p + n_q), 0.5 * (n_p * n_p + n_q * n_q)


@njit(cache=True)
def short_circuit_factors(theta_e, n_a, n_b, n_c, model):
    """PSC modulating function at electrical angle ``theta_e`` [rad] (see the sector form)."""
    return sector_short_circuit_factors(sector(theta_e), n_a, n_b, n_c, model)


@njit(cache=True)
def sawtooth(x):
    """MATLAB ``sawtooth``: rises from -1 at x = 0 to +1 at x = 2 pi, period 2 pi."""
    return (x % TWO_PI) / math.pi - 1.0


@njit(cache=True)
def eccentricity_shape(theta_e, s6, phi, model):
    """RE shape function ``s`` in sector ``s6``; the gain is multiplied by ``1 - Z s`` [-].

    ECCENTRICITY_PAIR (default), derived from the Reference law
    ``k_x = k (1 + zeta cos(theta_e + phi + beta_x))``: on the flat top the
    active pair (p driven +, q driven -) has gain ``k (2 + zeta (m_p + m_q))``,
    so ``s = -(cos(theta_e + phi + beta_p) + cos(theta_e + phi + beta_q))``,
    which equals ``cos(theta_e + phi + beta_idle)`` because the three cosines
    sum to zero; ``Z = zeta / 2`` in theory (c = 0.5; ``calibrate`` measures it).
    ECCENTRICITY_PAPER: the paper's Eq. 5,
    ``s = cos(theta_e + phi) + sawtooth(6 theta_e - pi) sin(theta_e + phi)``.
    """
    if model == ECCENTRICITY_PAPER:
        return math.cos(theta_e + phi) + sawtooth(6.0 * theta_e - math.pi) * math.sin(theta_e + phi)
    return math.cos(theta_e + phi + PHASE_OFFSET[IDLE_PHASE[s6]])


@njit(cache=True)
def eccentricity_offsets(phi):
    """``cos`` and ``sin`` of ``phi + beta_x`` for each phase x, a (2, 3) array: the fixed
    part of the pair law's angles, computed once a run."""
    out = np.empty((2, 3))
    for x in range(3):
        out[0, x] = math.cos(phi + PHASE_OFFSET[x])
        out[1, x] = math.sin(phi + PHASE_OFFSET[x])
    return out


@njit(cache=True)
def pair_eccentricity_coefficients(theta_e, s6, z, offsets, phase_working, unit_k, k_phase):
    """Per-phase coefficients under the ``pair`` RE law, written into ``k_phase`` [V s/rad].

    ``k_x = k N_x (1 + 2 Z cos(theta_e + phi + beta_x))``: the Reference law with
    ``zeta = 2 Z``, each phase's modulation scaled by its own working fraction
    ``N_x``. The pair's gain ``k_p + k_q`` is then ``2 k (f + Z (N_p m_p + N_q m_q))``
    with ``f = (N_p + N_q)/2``: with balanced phases exactly ``2 k f (1 - Z s)`` of
    :func:`eccentricity_shape`; with a shorted phase the modulation of that phase
    shrinks with it, as in the Reference (a short circuit and an eccentricity
    together otherwise leave a cross term the identification takes for error).
    ``offsets`` is :func:`eccentricity_offsets` of ``phi``: the cosines come from one
    ``cos`` and one ``sin`` of ``theta_e`` by the angle-sum rule (measured 17 ns a step
    against 23 ns for two cosines), the third from the two others (the three sum to zero).
    """
    p = POSITIVE_PHASE[s6]
    q = NEGATIVE_PHASE[s6]
    c = math.cos(theta_e)
    s = math.sin(theta_e)
    m_p = c * offsets[0, p] - s * offsets[1, p]
    m_q = c * offsets[0, q] - s * offsets[1, q]
    k_phase[p] = unit_k * phase_working[p] * (1.0 + 2.0 * z * m_p)
    k_phase[q] = unit_k * phase_working[q] * (1.0 + 2.0 * z * m_q)
    o = IDLE_PHASE[s6]
    k_phase[o] = unit_k * phase_working[o] * (1.0 - 2.0 * z * (m_p + m_q))
    return k_phase[p] + k_phase[q]


@njit(cache=True)
def equivalent_branch_step(current, current_ref, gain, a, drive, back, omega, vdc):
    """Exact RL update of the equivalent branch under a saturated ideal regulator [A].

    The regulator applies the voltage that brings the current to ``current_ref``
    at the end of the step (``i' = a i + (1 - a)(V - E)/R``, with the decay
    factor ``a = exp(-R dt/L)`` [-]), clipped to the bridge's +/-Vdc: the slew-rate
    limit of the real H-bridge without its switching ripple. ``drive = R / (1 - a)``
    [ohm] and ``back = (1 - a) / R`` [1/ohm] are precomputed per sector with ``a``
    (no division in the time loop).
    """
    emf = gain * omega
    needed = drive * (current_ref - a * current) + emf
    volts = clip(needed, vdc)
    return a * current + back * (volts - emf)


@njit(cache=True)
def commutation_step(
    pair, outgoing, current_ref, s6, theta_e, omega, k_phase, r_phase, l_phase, vdc, dt, duty
):
    """One step of a commutation: the pair current and the outgoing phase's freewheeling current.

    After a sector change the phase that left the pair (the new sector's idle
    phase) keeps its current ``outgoing`` [A], which freewheels through a diode
    to the rail its sign implies (0 V flowing in, Vdc flowing out) until it
    reaches zero. The regulated ``pair`` current ``y = (i_p - i_q)/2`` then
    shares the star point with it: ``i_p = y - i_out/2``, ``i_q = -y - i_out/2``.
    The bridge's mean duty ``d`` on the pair (``v_p = d Vdc``, ``v_q = (1-d) Vdc``,
    the mean of the hysteresis switching) is the one that brings ``y`` to the
    reference in this step, clipped to [0, 1] (then ``y`` lags: the commutation
    torque dip at speed). Under a PWM drive the duty is the loop's own (``duty`` in
    [0, 1]; a negative ``duty`` asks for the regulating one). Star-point circuit per phase
    ``L_x di_x/dt = v_x - v_n - e_x - R_x i_x``, ``sum i_x = 0``; explicit Euler.

    ``k_phase``, ``r_phase``, ``l_phase`` are per-phase (3,) arrays with the
    faults in them. Returns (pair current, outgoing current, torque [N m],
    equivalent current ``(|i_p| + |i_q| + |i_out|)/2 sign(T)`` [A]).
    """
    p = POSITIVE_PHASE[s6]
    q = NEGATIVE_PHASE[s6]
    o = IDLE_PHASE[s6]
    i_p = pair - 0.5 * outgoing
    i_q = -pair - 0.5 * outgoing
    e_p = k_phase[p] * trapezoid(theta_e + PHASE_OFFSET[p]) * omega
    e_q = k_phase[q] * trapezoid(theta_e + PHASE_OFFSET[q]) * omega
    shape_o = trapezoid(theta_e + PHASE_OFFSET[o])
    e_o = k_phase[o] * shape_o * omega
    a_p = -e_p - r_phase[p] * i_p
    a_q = -e_q - r_phase[q] * i_q
    v_o = 0.0 if outgoing > 0.0 else vdc
    w_o = v_o - e_o - r_phase[o] * outgoing
    g_p, g_q, g_o = 1.0 / l_phase[p], 1.0 / l_phase[q], 1.0 / l_phase[o]
    g = g_p + g_q + g_o
    n1 = vdc * (g_p - g_q) / g
    n0 = (a_p * g_p + (vdc + a_q) * g_q + w_o * g_o) / g
    c1 = 0.5 * ((vdc - n1) * g_p + (vdc + n1) * g_q)
    c0 = 0.5 * ((a_p - n0) * g_p - (vdc + a_q - n0) * g_q)
    if duty < 0.0:
        duty = min(1.0, max(0.0, ((current_ref - pair) / dt - c0) / c1))
    v_n = n0 + n1 * duty
    pair_new = pair + (c0 + c1 * duty) * dt
    outgoing_new = outgoing + (w_o - v_n) * g_o * dt
    if outgoing_new * outgoing <= 0.0:
        outgoing_new = 0.0  # the diode blocks: the commutation is over
    i_p = pair_new - 0.5 * outgoing_new
    i_q = -pair_new - 0.5 * outgoing_new
    torque = (
        k_phase[p] * trapezoid(theta_e + PHASE_OFFSET[p]) * i_p
        + k_phase[q] * trapezoid(theta_e + PHASE_OFFSET[q]) * i_q
        + k_phase[o] * shape_o * outgoing_new
    )
    return pair_new, outgoing_new, torque, equivalent_current(i_p, i_q, outgoing_new, torque)


@njit(cache=True)
def mean_demand(loop, pair_current, current_ref, speed, elec, dt):
    """The PWM loop over one Monitor step: the PI's updates at the period starts inside it
    (on the step's starting current) and the time mean of the applied demand [V]."""
    period = elec.pwm_period
    remaining = dt
    volt_seconds = 0.0
    while remaining > 0.0:
        if loop[L_CLOCK] >= period - EDGE_TOLERANCE:
            loop[L_CLOCK] = 0.0
            loop_sample(loop, pair_current, current_ref, speed, elec)
        h = min(period - loop[L_CLOCK], remaining)
        volt_seconds += loop[L_APPLIED] * h
        loop[L_CLOCK] += h
        remaining -= h
    return volt_seconds / dt


@njit(cache=True)
def simulate_monitor(drive, plant, faults, options, out):
    """Run the Monitor Model over ``drive.command.size`` controller periods.

    Same sampling contract as the Reference kernel: row k of ``out``
    (:class:`~emaprog.kernels.structs.MonitorOutputs`) holds the feedback at
    ``k T`` (offset and ADC applied, no noise) and the current averaged over the
    period ending at ``k T``. ``faults`` is a
    :class:`~emaprog.kernels.structs.MonitorFaults` (eccentricity as Z = c zeta).

    ``options.torque_gain_scale`` [-] and ``options.commutation_loss`` [s/rad]
    are the calibrated nominal equivalents: the torque per equivalent ampere is
    ``gain_scale 2 k_e (1 - commutation_loss |omega|)``. The second term stands
    for the Reference motor's commutation torque dips when ``commutation`` is
    off (the transients are not modelled); without it that Monitor explains
    the missing torque at speed with extra dry friction. With ``commutation``
    on, the dips come out of :func:`commutation_step` and the calibrated loss
    is zero.
    """
    elec, mech = plant.electrical, plant.mechanical
    n = drive.command.size
    substeps = options.substeps
    dt = plant.controller.period / substeps
    pp = elec.pole_pairs
    n_a = 1.0 - faults.short_a
    n_b = 1.0 - faults.short_b
    n_c = 1.0 - faults.short_c
    gain_scale = options.torque_gain_scale
    base_gain = gain_scale * 2.0 * elec.back_emf_constant
    base_r = 2.0 * elec.phase_resistance
    base_l = 2.0 * elec.phase_inductance
    # the PSC factors only change from sector to sector: tabulate them, and the RL decay
    sector_gain = np.empty(6)
    sector_r = np.empty(6)
    sector_decay = np.empty(6)
    sector_drive = np.empty(6)
    sector_back = np.empty(6)
    sector_l = np.empty(6)
    for s6 in range(6):
        f_psc, f_l = sector_short_circuit_factors(s6, n_a, n_b, n_c, options.short_circuit_model)
        sector_l[s6] = base_l * f_l
        sector_gain[s6] = base_gain * f_psc
        sector_r[s6] = base_r * f_psc
        sector_decay[s6] = math.exp(-base_r * f_psc * dt / (base_l * f_l))
        sector_drive[s6] = sector_r[s6] / (1.0 - sector_decay[s6])
        sector_back[s6] = (1.0 - sector_decay[s6]) / sector_r[s6]
    z = faults.eccentricity_z
    phi = faults.eccentricity_phase
    eccentric = z != 0.0
    offsets = eccentricity_offsets(phi)
    paper_shape = options.eccentricity_model == ECCENTRICITY_PAPER
    working = np.array([n_a, n_b, n_c])
    if options.short_circuit_model == SHORT_CIRCUIT_AVERAGED:
        n_eq = (n_a + n_b + n_c) / 3.0
        phase_working = np.array([n_eq, n_eq, n_eq])
    else:
        phase_working = working.copy()
    r_phase = phase_working * elec.phase_resistance
    l_phase = phase_working * phase_working * elec.phase_inductance
    unit_k = gain_scale * elec.back_emf_constant
    k_phase = unit_k * phase_working
    outgoing = 0.0  # [A] freewheeling current of the phase that last left the pair
    pwm = elec.regulator == PWM
    loop = np.zeros(len(LOOP_SLOTS))
    loop[L_CLOCK] = np.inf  # a PWM period starts with the first step
    sens = plant.sensors
    bank = filter_bank(sens, dt, plant.controller.period)
    chain = ChainState(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    line, line_rate = 0.0, 0.0  # the current line's filter
    point = sens.current_point
    theta_e0 = drive.electrical_angle
    recorded = drive.motor_angle
    last_sector = sector(theta_e0)
    theta_m = 0.0
    omega_m = 0.0
    theta_s = 0.0
    omega_s = 0.0
    position_int = 0.0
    speed_int = 0.0
    i = 0.0
    mean_current = 0.0
    for k in range(n):
        position_in, speed_in, chain = feedback_inputs(
            chain, theta_s, theta_m, omega_m, sens, bank, plant.controller.period
        )
        pos_meas, spd_meas, current_ref, position_int, speed_int = sample_and_control(
            drive.command[k], position_in, speed_in, 0.0, 0.0, position_int, speed_int, plant
        )
        out.position[k] = pos_meas
        out.speed[k] = spd_meas
        out.motor_angle[k] = theta_m
        out.current[k] = mean_current
        load = drive.load_torque[k] + drive.load_offset
        mean_current = 0.0
        synced = k < recorded.size and not math.isnan(recorded[k])
        if synced:
            ahead = recorded[k + 1] if k + 1 < recorded.size else math.nan
            slope = (ahead - recorded[k]) / substeps if not math.isnan(ahead) else 0.0
        for j in range(substeps):
            if synced:
                theta_e = pp * (recorded[k] + slope * j) + theta_e0
            else:
                theta_e = pp * theta_m + theta_e0
            s6 = sector(theta_e)
            gain = sector_gain[s6]
            if eccentric and paper_shape:
                ecc = 1.0 - z * eccentricity_shape(theta_e, s6, phi, ECCENTRICITY_PAPER)
                gain *= ecc
                for x in range(3):
                    k_phase[x] = unit_k * phase_working[x] * ecc
            elif eccentric:
                gain = pair_eccentricity_coefficients(
                    theta_e, s6, z, offsets, phase_working, unit_k, k_phase
                )
            if s6 != last_sector and options.commutation:
                # the new idle phase was in the old pair: it keeps its current
                idle = IDLE_PHASE[s6]
                outgoing = i if POSITIVE_PHASE[last_sector] == idle else -i
                i = 0.5 * i  # the common phase alone carries the old current
            last_sector = s6
            duty = -1.0
            volts = 0.0
            if pwm:
                volts = mean_demand(loop, i, current_ref, spd_meas, elec, dt)
                volts -= dead_time_loss(i, sector_l[s6], elec)
                duty = positive_duty(volts, elec.dc_bus_voltage)
            if outgoing != 0.0:
                i, outgoing, torque, measured = commutation_step(
                    i,
                    outgoing,
                    current_ref,
                    s6,
                    theta_e,
                    omega_m,
                    k_phase,
                    r_phase,
                    l_phase,
                    elec.dc_bus_voltage,
                    dt,
                    duty,
                )
            elif pwm:
                emf = gain * omega_m
                i = sector_decay[s6] * i + sector_back[s6] * (
                    clip(volts, elec.dc_bus_voltage) - emf
                )
                torque = gain * i
                measured = i
            else:
                i = equivalent_branch_step(
                    i,
                    current_ref,
                    gain,
                    sector_decay[s6],
                    sector_drive[s6],
                    sector_back[s6],
                    omega_m,
                    elec.dc_bus_voltage,
                )
                torque = gain * i
                measured = i
            torque *= max(0.0, 1.0 - options.commutation_loss * abs(omega_m))
            chain = analog_step(chain, theta_s, omega_m, bank)
            theta_m, omega_m, theta_s, omega_s, _ = mechanics_step(
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
            line, line_rate = advance(line, line_rate, measured, bank[F_CURRENT])
            if point:
                mean_current = line
            else:
                mean_current += line
        if not point:
            mean_current /= substeps


@njit(cache=True)
def moving_average(x, width, out):
    """Centred moving average of ``width`` samples (shrinking at the ends) into ``out``."""
    n = x.size
    half = width // 2
    csum = np.empty(n + 1)
    csum[0] = 0.0
    for k in range(n):
        csum[k + 1] = csum[k] + x[k]
    for k in range(n):
        lo = max(0, k - half)
        hi = min(n, k - half + width)
        out[k] = (csum[hi] - csum[lo]) / (hi - lo)


@njit(cache=True)
def unit_plant(plant, row):
    """``plant`` with the unit-to-unit values of one :data:`~emaprog.kernels.structs.UNIT_COLUMNS` row."""
    e, m = plant.electrical, plant.mechanical
    electrical = ElectricalParams(
        e.dc_bus_voltage,
        e.pole_pairs,
        row[U_PHASE_RESISTANCE],
        row[U_PHASE_INDUCTANCE],
        row[U_BACK_EMF_CONSTANT],
        e.current_limit,
        e.hysteresis_band,
        e.regulator,
        e.pwm_period,
        e.dead_time,
        e.loop_gain,
        e.loop_integral,
        e.emf_feedforward,
        e.loop_delay,
    )
    mechanical = MechanicalParams(
        row[U_MOTOR_INERTIA],
        row[U_MOTOR_VISCOUS],
        row[U_STATIC_FRICTION],
        row[U_DYNAMIC_FRICTION],
        m.gear_ratio,
        row[U_SURFACE_INERTIA],
        m.surface_damping,
        row[U_TRANSMISSION_STIFFNESS],
        m.transmission_damping,
        m.end_stop,
        m.end_stop_stiffness,
        m.end_stop_damping,
    )
    return Plant(electrical, mechanical, plant.controller, plant.sensors)


#: The signal whose error is formed about its mean (current, position, speed): the logged
#: position, whose sensor's zero a logger need not share with the drive, nor keep from one
#: recording to the next; an offset of it is not a fault (docs/reference.md, Scenario YAML,
#: ``signals``).
CENTRED_SIGNAL = 1


@njit(cache=True)
def _weighted_mean(x, weight):
    """``sum(weight x) / sum(weight)`` (0 without weight)."""
    acc = 0.0
    total = 0.0
    for k in range(x.size):
        acc += weight[k] * x[k]
        total += weight[k]
    return acc / total if total > 0.0 else 0.0


@njit(cache=True)
def _signal_norms(current, position, speed, sample_weight, centres):
    """Weighted squared norm of each measured signal (current, position, speed) about its
    centre."""
    norms = np.zeros(3)
    signals = (current, position, speed)
    for s in range(3):
        acc = 0.0
        for k in range(signals[s].size):
            acc += sample_weight[k] * (signals[s][k] - centres[s]) ** 2
        norms[s] = max(acc, 1e-30)
    return norms


def error_target(
    current, position, speed, weights, filter_width, sample_weight, sample_index, sample_fraction
):
    """The :class:`~emaprog.kernels.structs.ErrorTarget` of measured signals, with the value
    each signal's error is formed about (the position's weighted mean,
    :data:`CENTRED_SIGNAL`; 0 for the others) and each signal's weighted squared norm about
    it: the fitness's denominators, computed once per recording for every batch and for the
    noise floor."""
    centres = np.zeros(3)
    centres[CENTRED_SIGNAL] = _weighted_mean(position, sample_weight)
    norms = _signal_norms(current, position, speed, sample_weight, centres)
    return ErrorTarget(
        current,
        position,
        speed,
        weights,
        filter_width,
        sample_weight,
        sample_index,
        sample_fraction,
        centres,
        norms,
    )


@njit(cache=True)
def evaluate_population(faults, units, drive, plant, options, target, fitness):
    """Fitness of every candidate in one call (parallel over candidates).

    Parameters
    ----------
    faults : (m, 7) float64
        Rows of Monitor fault values in :class:`~emaprog.kernels.structs.MonitorFaults`
        order (friction, backlash, short a, b, c, Z, phi).
    units : (m, 11) or (1, 11) float64
        Each candidate's unit: :data:`~emaprog.kernels.structs.UNIT_COLUMNS`
        (inertias, viscous, friction, resistance, back-EMF constant, inductance,
        stiffness, constant hinge moment); one row is shared by every candidate.
    drive, plant, options : Drive, Plant, MonitorOptions
        ``plant``'s values outside the unit row are used as they are.
    target : ErrorTarget
        Measured signals already low-passed with ``target.filter_width``.
    fitness : (m,) float64, output
        ``sum_s w_s ||lp(MM_s) - target_s - o_s||^2 / ||target_s - m_s||^2``, both norms
        weighted sample by sample with ``target.sample_weight``; ``o_s`` and ``m_s`` are 0
        but for the position, where they are the weighted means of ``lp(MM_s) - target_s``
        and of ``target_s``.
    """
    _evaluate(faults, units, drive, plant, options, target, fitness, np.empty((0, 3, 0)))


@njit(cache=True)
def simulate_units(row, units, drive, plant, options, current, position, speed):
    """The Monitor outputs of one fault row under each unit row of ``units`` (m, 11), in one
    call (parallel over the units): ``current``, ``position``, ``speed`` (m, n) outputs. What
    commissioning's finite-difference Jacobian evaluates: one perturbed unit per row."""
    _simulate_units_parallel(
        row,
        units,
        drive,
        plant.electrical,
        plant.mechanical,
        plant.controller,
        plant.sensors,
        options,
        current,
        position,
        speed,
    )


@njit(cache=True, parallel=True)
def _simulate_units_parallel(
    row,
    units,
    drive,
    electrical,
    mechanical,
    controller,
    sensors,
    options,
    current,
    position,
    speed,
):
    for j in prange(units.shape[0]):
        out = _simulate_candidate(
            row, units[j], drive, Plant(electrical, mechanical, controller, sensors), options
        )
        current[j, :] = out.current
        position[j, :] = out.position
        speed[j, :] = out.speed


@njit(cache=True)
def _simulate_candidate(row, unit, drive, plant, options):
    """The Monitor outputs of one candidate row under its unit row."""
    n = drive.command.size
    candidate = MonitorFaults(row[0], row[1], row[2], row[3], row[4], row[5], row[6])
    own_drive = Drive(
        drive.command,
        drive.load_torque,
        drive.load_stiffness + unit[U_HINGE_STIFFNESS],
        unit[U_HINGE_MOMENT],
        drive.electrical_angle,
        drive.motor_angle,
    )
    out = MonitorOutputs(np.empty(n), np.empty(n), np.empty(n), np.empty(n))
    simulate_monitor(own_drive, unit_plant(plant, unit), candidate, options, out)
    return out


@njit(cache=True)
def _filtered_at_instants(signal, target, filtered, model):
    """A Monitor signal as the error sees it: the 1 ms moving average (into ``filtered``),
    read at the recorded instants by linear interpolation (into ``model``)."""
    moving_average(signal, target.filter_width, filtered)
    for k in range(model.size):
        i = target.sample_index[k]
        f = target.sample_fraction[k]
        model[k] = filtered[i] if f == 0.0 else filtered[i] + f * (filtered[i + 1] - filtered[i])


@njit(cache=True)
def evaluate_residuals(faults, units, drive, plant, options, target, residuals):
    """The weighted residual of every candidate in one call (parallel over candidates).

    ``residuals`` : (m, 3, n_rec) float64, output:
    ``sqrt(w_s sample_weight_k / ||target_s||^2) (lp(MM_s)_k - target_s,k - o_s)`` (``o_s``
    as in :func:`evaluate_population`); its squared
    sum over (s, k) is the candidate's fitness of :func:`evaluate_population` (a
    zero-weight signal's rows are 0). For least-squares polishing and Jacobians.
    """
    _evaluate(faults, units, drive, plant, options, target, np.empty(faults.shape[0]), residuals)


@njit(cache=True)
def _evaluate(faults, units, drive, plant, options, target, fitness, residuals):
    """:func:`_batch_parallel` with the plant in parts (numba's parallel loop takes flat tuples)."""
    _batch_parallel(
        faults,
        units,
        drive,
        plant.electrical,
        plant.mechanical,
        plant.controller,
        plant.sensors,
        options,
        target,
        fitness,
        residuals,
    )


@njit(cache=True, parallel=True)
def _batch_parallel(
    faults,
    units,
    drive,
    electrical,
    mechanical,
    controller,
    sensors,
    options,
    target,
    fitness,
    residuals,
):
    """The one evaluation of a batch of candidates: each candidate's Monitor run, its
    signals filtered and read at the recorded instants, then either its fitness (into
    ``fitness``) or, when ``residuals`` has rows, its weighted residual vector. numba's
    parallel loop takes flat tuples only: the plant comes in parts."""
    centres, norms = target.centres, target.norms
    shared = units.shape[0] == 1
    with_residuals = residuals.shape[0] > 0
    n = drive.command.size
    for j in prange(faults.shape[0]):
        out = _simulate_candidate(
            faults[j],
            units[0] if shared else units[j],
            drive,
            Plant(electrical, mechanical, controller, sensors),
            options,
        )
        filtered = np.empty(n)
        model = np.empty(target.sample_index.size)
        signals = (out.current, out.position, out.speed)
        targets = (target.current, target.position, target.speed)
        total = 0.0
        for s in range(3):
            if target.weights[s] == 0.0:
                if with_residuals:
                    residuals[j, s, :] = 0.0
                continue
            _filtered_at_instants(signals[s], target, filtered, model)
            measured = targets[s]
            offset = 0.0  # o_s of evaluate_population
            if s == CENTRED_SIGNAL:
                offset = _weighted_mean(model, target.sample_weight) - centres[s]
            if with_residuals:
                scale = target.weights[s] / norms[s]
                for k in range(measured.size):
                    residuals[j, s, k] = math.sqrt(scale * target.sample_weight[k]) * (
                        model[k] - measured[k] - offset
                    )
            else:
                acc = 0.0
                for k in range(measured.size):
                    acc += target.sample_weight[k] * (model[k] - measured[k] - offset) ** 2
                total += target.weights[s] * acc / norms[s]
        fitness[j] = total
