"""Monitor Model: single-phase equivalent BLDC (no PWM) + the shared controller and mechanics.

The equivalent branch is the active phase pair in series: ``R_eq = 2 R``,
``L_eq = 2 L``, torque gain = back-EMF gain ``G = 2 k_e`` (N m/A = V s/rad),
driven by an ideal current regulator whose voltage saturates at +/-Vdc like
the Reference Model's H-bridge. Electrical faults enter through modulating
functions of the rotor angle (SPEC 1), using the angle conventions and sector
tables of :mod:`emaprog.kernels.bldc`, so both models agree on where each
phase is active.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .bldc import IDLE_PHASE, NEGATIVE_PHASE, PHASE_OFFSET, POSITIVE_PHASE, TWO_PI, sector
from .control import clip, controller_update, quantize
from .mechanics import mechanics_step
from .structs import FaultParams

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
def equivalent_branch_step(current, current_ref, gain, resistance, a, omega, vdc):
    """Exact RL update of the equivalent branch under a saturated ideal regulator [A].

    The regulator applies the voltage that brings the current to ``current_ref``
    at the end of the step (``i' = a i + (1 - a)(V - E)/R``, with the decay
    factor ``a = exp(-R dt/L)`` [-] precomputed per sector), clipped to the
    bridge's +/-Vdc: the slew-rate limit of the real H-bridge without its
    switching ripple.
    """
    emf = gain * omega
    needed = resistance * (current_ref - a * current) / (1.0 - a) + emf
    volts = clip(needed, vdc)
    return a * current + (1.0 - a) * (volts - emf) / resistance


@njit(cache=True)
def simulate_monitor(command, load_torque, load_stiffness, elec, mech, ctrl, sens, faults,
                     short_circuit_model, eccentricity_model, gain_scale, commutation_loss,
                     substeps, position, speed, current, motor_angle):
    """Run the Monitor Model over ``command.size`` controller periods.

    Same sampling contract as the Reference kernel: row k holds the feedback at
    ``k T`` (offset and ADC applied, no noise) and the current averaged over the
    period ending at ``k T``. ``faults.ecc_magnitude`` is Z (already ``c zeta``).

    ``gain_scale`` [-] and ``commutation_loss`` [s/rad] are the calibrated
    nominal equivalents: the torque per equivalent ampere is
    ``gain_scale 2 k_e (1 - commutation_loss |omega|)``. The second term stands
    for the Reference motor's commutation torque dips, whose share of a
    sector grows with speed (the incoming phase's current rise is limited by
    ``Vdc - 2E``); without it the Monitor explains the missing torque at speed
    with extra dry friction.
    """
    n = command.size
    dt = ctrl.period / substeps
    pp = elec.pole_pairs
    n_a = 1.0 - faults.short_a
    n_b = 1.0 - faults.short_b
    n_c = 1.0 - faults.short_c
    base_gain = gain_scale * 2.0 * elec.back_emf_constant
    base_r = 2.0 * elec.phase_resistance
    base_l = 2.0 * elec.phase_inductance
    # the PSC factors only change from sector to sector: tabulate them, and the RL decay
    sector_gain = np.empty(6)
    sector_r = np.empty(6)
    sector_decay = np.empty(6)
    for s6 in range(6):
        f_psc, f_l = sector_short_circuit_factors(s6, n_a, n_b, n_c, short_circuit_model)
        sector_gain[s6] = base_gain * f_psc
        sector_r[s6] = base_r * f_psc
        sector_decay[s6] = math.exp(-base_r * f_psc * dt / (base_l * f_l))
    eccentric = faults.ecc_magnitude != 0.0
    theta_m = 0.0
    omega_m = 0.0
    theta_s = 0.0
    omega_s = 0.0
    position_int = 0.0
    speed_int = 0.0
    i = 0.0
    mean_current = 0.0
    for k in range(n):
        pos_meas = quantize(theta_s + sens.position_offset, sens.position_lsb, sens.position_range)
        spd_meas = quantize(omega_m, sens.speed_lsb, sens.speed_range)
        position[k] = pos_meas
        speed[k] = spd_meas
        motor_angle[k] = theta_m
        current[k] = mean_current
        current_ref, position_int, speed_int = controller_update(
            command[k], pos_meas, spd_meas, position_int, speed_int, ctrl)
        mean_current = 0.0
        for _ in range(substeps):
            theta_e = pp * theta_m
            s6 = sector(theta_e)
            gain = sector_gain[s6]
            if eccentric:
                gain *= 1.0 - faults.ecc_magnitude * eccentricity_shape(
                    theta_e, s6, faults.ecc_phase, eccentricity_model)
            i = equivalent_branch_step(i, current_ref, gain, sector_r[s6], sector_decay[s6],
                                       omega_m, elec.dc_bus_voltage)
            torque = gain * i * max(0.0, 1.0 - commutation_loss * abs(omega_m))
            theta_m, omega_m, theta_s, omega_s, _, _ = mechanics_step(
                theta_m, omega_m, theta_s, omega_s, torque, load_torque[k], load_stiffness,
                faults.friction, faults.backlash, mech, dt)
            mean_current += i
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


@njit(cache=True, parallel=True)
def evaluate_population(candidates, command, load_torque, load_stiffness, elec, mech, ctrl, sens,
                        short_circuit_model, eccentricity_model, gain_scale, commutation_loss,
                        substeps, target_current, target_position, target_speed, weights, filter_width,
                        first_sample, fitness):
    """Fitness of every candidate in one call (parallel over candidates).

    Parameters
    ----------
    candidates : (m, 7) float64
        Rows of fault values in :class:`~emaprog.faults.FaultParams` order
        (friction, backlash, short a, b, c, Z, phi).
    target_current, target_position, target_speed : (n,) float64
        Measured signals already low-passed with the same ``filter_width``.
    weights : (3,) float64
        Weights of the normalised current, position and speed errors.
    first_sample : int
        Samples before this one are left out of the error (start-up).
    fitness : (m,) float64, output
        ``sum_s w_s ||lp(MM_s) - target_s||^2 / ||target_s||^2``.
    """
    n = command.size
    norms = np.zeros(3)
    targets = (target_current, target_position, target_speed)
    for s in range(3):
        acc = 0.0
        for k in range(first_sample, n):
            acc += targets[s][k] ** 2
        norms[s] = max(acc, 1e-30)
    for j in prange(candidates.shape[0]):
        row = candidates[j]
        faults = FaultParams(row[0], row[1], row[2], row[3], row[4], row[5], row[6])
        pos = np.empty(n)
        spd = np.empty(n)
        cur = np.empty(n)
        ang = np.empty(n)
        simulate_monitor(command, load_torque, load_stiffness, elec, mech, ctrl, sens, faults,
                        short_circuit_model, eccentricity_model, gain_scale, commutation_loss,
                        substeps, pos, spd, cur, ang)
        total = 0.0
        filtered = np.empty(n)
        signals = (cur, pos, spd)
        for s in range(3):
            if weights[s] == 0.0:
                continue
            moving_average(signals[s], filter_width, filtered)
            acc = 0.0
            target = targets[s]
            for k in range(first_sample, n):
                acc += (filtered[k] - target[k]) ** 2
            total += weights[s] * acc / norms[s]
        fitness[j] = total

