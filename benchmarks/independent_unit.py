"""An actuator simulator written apart from emaprog: a check of the rig workflow from outside.

Nothing here imports emaprog or copies its kernels (a test asserts the first): the equations
are written from the physics of a real unit, in another form than emaprog's Reference Model
wherever a real unit differs from it, so that what the rig workflow reads from these files
measures emaprog on a unit it did not write:

* **drive**: a three-leg inverter switched edge by edge (centre-aligned carrier, dead time
  on every transition, the idle leg's terminal set by its freewheeling diodes or floating),
  Hall-sensor six-step commutation, a PI loop on the pair current sampled at the carrier's
  valley through the drive's own current sensors (gain errors), back-EMF feed-forward from
  the resolver speed, one period of computation delay;
* **motor**: back-EMF with rounded edges (the trapezoid smoothed over ``emf_edge_deg``), cogging
  torque, the winding resistance warming during the recording;
* **mechanics**: LuGre friction with a Stribeck curve at the motor (bristle dynamics, not a
  stick/slip switch), a gear, a compliant transmission with a dead band, the surface under a
  hinge moment with an aerodynamic spring;
* **logger**: per-phase current gains and offsets, anti-alias filters, a resolver speed
  differenced and low-passed, noise, ADC steps, a rotor electrical zero away from the
  position sensor's zero, written as a European CSV (``;`` and decimal comma).

The faults follow emaprog's documented catalogue (docs/reference.md, "Faults"): friction
multiplies the static and dynamic dry friction, backlash is the total play at the output,
a short circuit of a fraction ``f`` of a phase's turns gives ``N = 1 - f``, ``R N``,
``L N^2``, ``k N``, a static eccentricity ``zeta`` at ``phi`` modulates each phase's
coefficient by ``1 + zeta cos(theta_e - beta_x + phi)`` on the argument of its back-EMF.

Run ``python benchmarks/independent_unit.py DIR`` to write a unit's folder (recordings,
column map, truth); :mod:`independent_rig` runs the documented rig commands over it.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
from numba import njit

#: [s] integration step: a quarter of the dead time, so every switching edge is resolved.
STEP = 0.25e-6
#: [s] time the unit holds its position under the hinge moment before the logger starts.
SETTLE = 0.15


@dataclass(frozen=True)
class Unit:
    """A unit's physical values (a small primary flight-control EMA; SI units)."""

    dc_bus: float = 270.0
    pole_pairs: int = 4
    resistance: float = 1.2
    inductance: float = 2.5e-3
    k_e: float = 0.15
    current_limit: float = 25.0
    motor_inertia: float = 1.5e-4
    motor_viscous: float = 5.0e-4
    static_friction: float = 0.12
    dynamic_friction: float = 0.08
    stribeck_speed: float = 2.0  # [rad/s] motor
    bristle_stiffness: float = 2.0e3  # [N m/rad] LuGre sigma_0
    gear_ratio: float = 180.0
    surface_inertia: float = 3.0
    surface_damping: float = 50.0
    stiffness: float = 3.0e5
    transmission_damping: float = 300.0
    cogging: float = 0.02  # [N m] amplitude, 6 P periods a turn
    warming: float = 0.02  # winding resistance rise over the recording [-]
    emf_edge_deg: float = 12.0  # [deg electrical] the back-EMF trapezoid's edges rounded over it
    # drive
    pwm_frequency: float = 20e3
    dead_time: float = 1e-6
    current_bandwidth: float = 1500.0  # [Hz]
    controller_rate: float = 10e3
    position_gain: float = 10800.0
    speed_gain: float = 0.15
    speed_integral: float = 15.0
    speed_limit: float = 600.0
    # logger
    electrical_zero_deg: float = 0.0  # rotor electrical angle where the position reads 0
    hall_error_deg: float = 2.0
    gains: tuple[float, float, float] = (1.0, 1.0, 1.0)
    offsets: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [A]
    filter_hz: float = 2000.0
    speed_filter_hz: float = 1000.0
    resolver_bits: int = 16
    position_noise: float = 2e-5
    current_noise: float = 0.05
    position_offset: float = 1e-4


@dataclass(frozen=True)
class Faults:
    friction: float = 1.0
    backlash: float = 0.0
    short_circuit: tuple[float, float, float] = (0.0, 0.0, 0.0)
    zeta: float = 0.0
    phi: float = 0.0


@dataclass(frozen=True)
class Test:
    """The standard test command: a chirp on the surface position from rest."""

    amplitude: float = 0.05
    f0: float = 0.5
    f1: float = 10.0
    duration: float = 0.5
    hinge_moment: float = 0.0
    spring: float = 0.0  # [N m/rad]
    rate: float = 10e3  # logger
    seed: int = 0
    pre_roll: float = 0.0  # [s] the logger runs this long at rest before the command starts


def emf_shape(edge_deg: float, points: int = 3600) -> np.ndarray:
    """The unit's back-EMF shape over one electrical turn: a trapezoid (flat 120 deg, ramps
    60 deg, peak at 90 deg) smoothed by a moving average over ``edge_deg``."""
    theta = np.arange(points) * 360.0 / points
    trap = np.clip((90.0 - np.abs(((theta - 90.0 + 180.0) % 360.0) - 180.0)) / 30.0, -1, 1)
    width = max(int(round(edge_deg * points / 360.0)), 1)
    kernel = np.ones(width) / width
    padded = np.concatenate([trap[-width:], trap, trap[:width]])
    return np.convolve(padded, kernel, mode="same")[width:-width].copy()


@njit(cache=True)
def _shape_at(table, angle):
    n = table.size
    x = (angle % (2.0 * math.pi)) / (2.0 * math.pi) * n
    j = int(x)
    w = x - j
    return table[j % n] * (1.0 - w) + table[(j + 1) % n] * w


@njit(cache=True)
def _filter2(state, u, wc, dt):
    """One step of a second-order Butterworth low-pass (x'' + sqrt2 wc x' + wc^2 x = wc^2 u),
    semi-implicit; state = (x, x')."""
    acc = wc * wc * (u - state[0]) - math.sqrt(2.0) * wc * state[1]
    state[1] += acc * dt
    state[0] += state[1] * dt


@njit(cache=True)
def _chirp(t, amp, f0, f1, duration):
    """The test command at ``t`` from its start: a linear chirp, 0 before and after it."""
    if t < 0.0 or t > duration:
        return 0.0
    return amp * math.sin(2.0 * math.pi * (f0 * t + 0.5 * (f1 - f0) / duration * t * t))


@njit(cache=True)
def _star_rates(a, inductance, di):
    """The phase currents' rates of a star winding with all three phases conducting:
    ``L_x di_x/dt + v_n = a_x`` (``a_x``: terminal voltage less the resistive drop and the
    back-EMF) with ``sum di_x = 0`` fixes the neutral ``v_n``; written into ``di``."""
    num = 0.0
    den = 0.0
    for x in range(3):
        num += a[x] / inductance[x]
        den += 1.0 / inductance[x]
    vn = num / den
    for x in range(3):
        di[x] = (a[x] - vn) / inductance[x]


@njit(cache=True)
def _run(
    u_vals,  # unit scalars, see simulate
    table,
    n_scale,
    k_scale,
    gains,
    offsets,
    friction,
    backlash,
    zeta,
    phi,
    amp,
    f0,
    f1,
    duration,
    hinge,
    spring,
    log_dt,
    total_samples,
    settle,
    pre_roll,
    noise,  # (samples, 5): position, ia, ib, ic, resolver jitter (unit normal)
):
    (
        vdc,
        pp,
        r0,
        l0,
        ke,
        ilim,
        jm,
        bm,
        fs,
        fc,
        vs,
        sigma0,
        gear,
        js,
        cs,
        ks,
        ct,
        cog,
        warming,
        fpwm,
        td,
        fbw,
        fctl,
        kpos,
        kspd,
        kispd,
        wlim,
        ezero,
        hall_err,
        ffilt,
        fspd,
        rbits,
        pos_noise,
        cur_noise,
        pos_off,
    ) = u_vals
    dt = 2.5e-7
    two_pi = 2.0 * math.pi
    tpwm = 1.0 / fpwm
    steps_pwm = int(round(tpwm / dt))
    steps_ctl = int(round(1.0 / fctl / dt))
    steps_log = int(round(log_dt / dt))
    settle_steps = int(round(settle / dt))
    n_steps = settle_steps + total_samples * steps_log
    wc = two_pi * ffilt
    beta = np.array([0.0, two_pi / 3.0, 2.0 * two_pi / 3.0])
    R = np.empty(3)
    L = np.empty(3)
    K = np.empty(3)
    for x in range(3):
        R[x] = r0 * n_scale[x]
        L[x] = l0 * n_scale[x] ** 2
        K[x] = ke * k_scale[x]
    # PI gains of the current loop on the pair (2 L, 2 R): pole-zero cancellation
    kp_i = 2.0 * l0 * two_pi * fbw
    ki_i = 2.0 * r0 * two_pi * fbw
    # state
    i = np.zeros(3)
    thm = 0.0
    wm = 0.0
    ths = 0.0
    ws = 0.0
    z = 0.0  # LuGre bristle
    sigma1 = 2.0 * math.sqrt(sigma0 * jm)
    pos_f = np.zeros(2)
    cur_f = np.zeros((3, 2))
    # controller
    integ_w = 0.0
    i_dem = 0.0
    w_meas = 0.0
    w_filt = 0.0
    q = two_pi / 2.0**rbits
    res_prev = 0.0
    res_init = False
    # current loop
    integ_i = 0.0
    u_next = 0.0
    u_now = 0.0
    leg_cmd = np.zeros(3)  # duty per leg; -1 = leg off
    leg_cmd[:] = -1.0
    leg_now = np.zeros(3)
    leg_now[:] = -1.0
    leg_state = np.zeros(3, dtype=np.int64)  # 1 upper on, -1 lower on, 0 both off
    last_cmd = np.zeros(3, dtype=np.int64)
    dead_left = np.zeros(3)
    out = np.zeros((total_samples, 9))
    alpha = 1.0 - math.exp(-two_pi * fspd / fctl)
    v = np.zeros(3)
    e_shape = np.zeros(3)
    for k in range(n_steps):
        t_rec = (k - settle_steps) * dt
        the = pp * thm + ezero
        # ---- controller (position, speed) at its rate
        if k % steps_ctl == 0:
            # resolver on the motor: quantised angle, differenced, low-passed
            res = math.floor(thm / q) * q
            if res_init:
                w_raw = (res - res_prev) * fctl
            else:
                w_raw = 0.0
                res_init = True
            res_prev = res
            w_filt += alpha * (w_raw - w_filt)
            w_meas = w_filt
            cmd = _chirp(t_rec - pre_roll, amp, f0, f1, duration)
            pos_meas = pos_f[0] + pos_off
            w_dem = kpos * (cmd - pos_meas)
            if w_dem > wlim:
                w_dem = wlim
            elif w_dem < -wlim:
                w_dem = -wlim
            err_w = w_dem - w_meas
            trial = kspd * err_w + integ_w + kispd * err_w / fctl
            if abs(trial) < ilim:
                integ_w += kispd * err_w / fctl
                i_dem = trial
            else:
                i_dem = ilim if trial > 0 else -ilim
        # ---- current loop at the carrier's valley
        if k % steps_pwm == 0:
            u_now = u_next
            # sector from the Hall sensors (mounted hall_err off)
            hall = the + hall_err
            best = 0
            worst = 0
            # the sector's pair: the phases whose ideal trapezoid is highest and lowest at the
            # sector's centre
            sector = int(math.floor(((hall % two_pi) - math.pi / 6.0) / (math.pi / 3.0))) % 6
            centre = math.pi / 6.0 + (sector + 0.5) * math.pi / 3.0
            hi = -2.0
            lo = 2.0
            for x in range(3):
                s = _shape_at(table, centre - beta[x])
                if s > hi:
                    hi = s
                    best = x
                if s < lo:
                    lo = s
                    worst = x
            meas = np.empty(3)
            for x in range(3):
                meas[x] = gains[x] * i[x] + offsets[x]
            i_pair = 0.5 * (meas[best] - meas[worst])
            err = i_dem - i_pair
            trial = kp_i * err + integ_i + ki_i * err * tpwm + 2.0 * ke * w_meas
            if abs(trial) < vdc:
                integ_i += ki_i * err * tpwm
                u_cmd = trial
            else:
                u_cmd = vdc if trial > 0 else -vdc
            u_next = u_cmd  # one period of computation delay
            for x in range(3):
                leg_now[x] = -1.0
            leg_now[best] = 0.5 + 0.5 * u_now / vdc
            leg_now[worst] = 0.5 - 0.5 * u_now / vdc
        # ---- legs: centre-aligned carrier, dead time
        phase_in = (k % steps_pwm) / steps_pwm
        carrier = 1.0 - 2.0 * phase_in if phase_in < 0.5 else 2.0 * phase_in - 1.0
        for x in range(3):
            if leg_now[x] < 0.0:
                c = 0
            else:
                c = 1 if leg_now[x] > carrier else -1
            if c != last_cmd[x]:
                if c != 0 and last_cmd[x] != 0:
                    dead_left[x] = td
                last_cmd[x] = c
            if dead_left[x] > 0.0:
                dead_left[x] -= dt
                leg_state[x] = 0
            else:
                leg_state[x] = c
        # ---- electrical
        warm = 1.0 + warming * max(t_rec, 0.0) / duration
        a = np.empty(3)
        fixed = np.zeros(3, dtype=np.int64)
        for x in range(3):
            ang = the - beta[x]
            kx = K[x] * (1.0 + zeta * math.cos(ang + phi))
            e_shape[x] = kx * _shape_at(table, ang)
            if leg_state[x] == 1:
                v[x] = vdc
                fixed[x] = 1
            elif leg_state[x] == -1:
                v[x] = 0.0
                fixed[x] = 1
            elif i[x] > 0.0:
                v[x] = 0.0
                fixed[x] = 1
            elif i[x] < 0.0:
                v[x] = vdc
                fixed[x] = 1
            a[x] = v[x] - R[x] * warm * i[x] - e_shape[x] * wm
        n_fixed = fixed[0] + fixed[1] + fixed[2]
        di = np.zeros(3)
        if n_fixed == 3:
            _star_rates(a, L, di)
        elif n_fixed == 2:
            p = -1
            qx = -1
            o = -1
            for x in range(3):
                if fixed[x] == 1:
                    if p < 0:
                        p = x
                    else:
                        qx = x
                else:
                    o = x
            dip = (a[p] - a[qx]) / (L[p] + L[qx])
            vn = a[p] - L[p] * dip
            v_open = e_shape[o] * wm + vn
            if v_open > vdc or v_open < 0.0:
                v[o] = vdc if v_open > vdc else 0.0
                a[o] = v[o] - e_shape[o] * wm
                _star_rates(a, L, di)
            else:
                di[p] = dip
                di[qx] = -dip
        for x in range(3):
            new = i[x] + di[x] * dt
            if leg_state[x] == 0 and i[x] != 0.0 and new * i[x] <= 0.0:
                new = 0.0  # the freewheeling diode blocks
            i[x] = new
        # enforce the star's sum on the conducting phases
        s = i[0] + i[1] + i[2]
        if abs(s) > 0.0:
            nz = 0
            for x in range(3):
                if i[x] != 0.0:
                    nz += 1
            if nz > 0:
                for x in range(3):
                    if i[x] != 0.0:
                        i[x] -= s / nz
        torque = 0.0
        for x in range(3):
            torque += e_shape[x] * i[x]
        torque += cog * math.sin(6.0 * pp * thm)
        # ---- mechanics: LuGre friction at the motor, compliant transmission with play
        g = friction * (fc + (fs - fc) * math.exp(-((wm / vs) ** 2)))
        # the bristles relax toward g/sigma0 at the rate sigma0 |w| / g: exactly over the step
        # (explicitly it would be unstable at full speed)
        z_slide = g / sigma0 if wm >= 0.0 else -g / sigma0
        z_new = z_slide + (z - z_slide) * math.exp(-sigma0 * abs(wm) / g * dt)
        if wm == 0.0:
            z_new = z
        dz = (z_new - z) / dt + 0.0
        if abs(wm) * dt > 0.0 and sigma0 * abs(wm) / g * dt < 1e-3:
            dz = wm - sigma0 * abs(wm) * z / g
            z_new = z + dz * dt
        f_fric = sigma0 * z + sigma1 * dz
        z = z_new
        twist = thm / gear - ths
        rate = wm / gear - ws
        half = 0.5 * backlash
        if twist > half:
            link = max(ks * (twist - half) + ct * rate, 0.0)
        elif twist < -half:
            link = min(ks * (twist + half) + ct * rate, 0.0)
        else:
            link = 0.0
        wm += (torque - bm * wm - f_fric - link / gear) * dt / jm
        thm += wm * dt
        ws += (link - cs * ws - hinge - spring * ths) * dt / js
        ths += ws * dt
        # ---- sensors (continuous anti-alias filters)
        _filter2(pos_f, ths, wc, dt)
        for x in range(3):
            cf = cur_f[x]
            _filter2(cf, gains[x] * i[x] + offsets[x], wc, dt)
        # ---- logger: point sampling
        if k >= settle_steps and (k - settle_steps) % steps_log == 0:
            j = (k - settle_steps) // steps_log
            if j < total_samples:
                out[j, 0] = t_rec
                out[j, 1] = _chirp(t_rec - pre_roll, amp, f0, f1, duration)
                out[j, 2] = pos_f[0] + pos_off + pos_noise * noise[j, 0]
                out[j, 3] = w_meas
                for x in range(3):
                    out[j, 4 + x] = cur_f[x][0] + cur_noise * noise[j, 1 + x]
                out[j, 7] = torque  # the truth, not logged
                out[j, 8] = thm
    return out


def simulate(unit: Unit, faults: Faults, test: Test) -> dict[str, np.ndarray]:
    """One recording of the test command: the logger's channels at its rate (SI units), and
    the unit's true electromagnetic torque and motor angle (``true_*``, not logged)."""
    n = np.array([1.0 - f for f in faults.short_circuit])
    vals = (
        unit.dc_bus,
        float(unit.pole_pairs),
        unit.resistance,
        unit.inductance,
        unit.k_e,
        unit.current_limit,
        unit.motor_inertia,
        unit.motor_viscous,
        unit.static_friction,
        unit.dynamic_friction,
        unit.stribeck_speed,
        unit.bristle_stiffness,
        unit.gear_ratio,
        unit.surface_inertia,
        unit.surface_damping,
        unit.stiffness,
        unit.transmission_damping,
        unit.cogging,
        unit.warming,
        unit.pwm_frequency,
        unit.dead_time,
        unit.current_bandwidth,
        unit.controller_rate,
        unit.position_gain,
        unit.speed_gain,
        unit.speed_integral,
        unit.speed_limit,
        math.radians(unit.electrical_zero_deg),
        math.radians(unit.hall_error_deg),
        unit.filter_hz,
        unit.speed_filter_hz,
        float(unit.resolver_bits),
        unit.position_noise,
        unit.current_noise,
        unit.position_offset,
    )
    samples = int(round((test.pre_roll + test.duration) * test.rate)) + 1
    noise = np.random.default_rng(test.seed).standard_normal((samples, 5))
    out = _run(
        vals,
        emf_shape(unit.emf_edge_deg),
        n,
        n,
        np.asarray(unit.gains, float),
        np.asarray(unit.offsets, float),
        faults.friction,
        faults.backlash,
        faults.zeta,
        faults.phi,
        test.amplitude,
        test.f0,
        test.f1,
        test.duration,
        test.hinge_moment,
        test.spring,
        1.0 / test.rate,
        samples,
        SETTLE,
        test.pre_roll,
        noise,
    )
    names = (
        "time",
        "command",
        "position",
        "speed",
        "current_a",
        "current_b",
        "current_c",
        "true_torque",
        "true_motor_angle",
    )
    return {name: out[:, j] for j, name in enumerate(names)}


#: The logger's layout: a European export (``;``, decimal comma), a title line, a units row.
HEADER = ("t [s]", "Sollwert [deg]", "Istwert [deg]", "n [1/min]", "I_U [A]", "I_V [A]", "I_W [A]")
COLUMN_MAP = """\
# Column map of the independent unit's logger (a European export: ';' and decimal comma).
time: {column: "t [s]", unit: s}
command: {column: "Sollwert [deg]", unit: deg}
position: {column: "Istwert [deg]", unit: deg}
speed: {column: "n [1/min]", unit: rpm}
current_a: {column: "I_U [A]", unit: A}
current_b: {column: "I_V [A]", unit: A}
current_c: {column: "I_W [A]", unit: A}
"""


#: The column of the drive's resolver angle, where the logger records it (``--motor-angle``).
RESOLVER_HEADER = "Rotorlage [deg]"
RESOLVER_MAP = f'motor_angle: {{column: "{RESOLVER_HEADER}", unit: deg}}\n'
#: The resolver's resolution [rad]: 16 bits a turn.
RESOLVER_LSB = 2.0 * math.pi / 65536


def write_csv(path: Path, rec: dict[str, np.ndarray], motor_angle: bool = False) -> None:
    """The recording as the logger exports it; with ``motor_angle`` also the drive's
    resolver angle, 16 bits within a turn (0-360 deg, as a resolver reads it)."""
    cols = [
        rec["time"],
        np.degrees(rec["command"]),
        np.degrees(rec["position"]),
        rec["speed"] * 60.0 / (2.0 * math.pi),
        rec["current_a"],
        rec["current_b"],
        rec["current_c"],
    ]
    fmt = ["{:.5f}", "{:.5f}", "{:.5f}", "{:.2f}", "{:.4f}", "{:.4f}", "{:.4f}"]
    header = list(HEADER)
    if motor_angle:
        counts = np.floor(rec["true_motor_angle"] / RESOLVER_LSB) * RESOLVER_LSB
        cols.append(np.degrees(np.mod(counts, 2.0 * math.pi)))
        fmt.append("{:.4f}")
        header.append(RESOLVER_HEADER)
    lines = ["Pruefstand 3; Aktuator-Pruefung", ";".join(header)]
    for j in range(rec["time"].size):
        lines.append(";".join(f.format(c[j]).replace(".", ",") for f, c in zip(fmt, cols)))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def spread_unit(rng: np.random.Generator) -> Unit:
    """A unit off the nominal values by build tolerances, logger errors and a random
    electrical zero."""

    def f(t: float) -> float:
        return float(1.0 + rng.uniform(-t, t))

    base = Unit()
    return replace(
        base,
        motor_inertia=base.motor_inertia * f(0.10),
        surface_inertia=base.surface_inertia * f(0.10),
        motor_viscous=base.motor_viscous * f(0.30),
        static_friction=base.static_friction * f(0.15),
        dynamic_friction=base.dynamic_friction * f(0.15),
        resistance=base.resistance * f(0.10),
        inductance=base.inductance * f(0.10),
        k_e=base.k_e * f(0.03),
        stiffness=base.stiffness * f(0.20),
        electrical_zero_deg=float(rng.uniform(-180.0, 180.0)),
        gains=tuple(float(g) for g in 1.0 + rng.uniform(-0.01, 0.01, 3)),
        offsets=tuple(float(o) for o in rng.uniform(-0.01, 0.01, 3)),
    )


#: The unit's differences of form from emaprog's Reference that can be made ideal one at a
#: time (``independent_rig.py --ideal``), each the unit's fields it sets.
IDEALS: dict[str, Callable[[Unit], dict]] = {
    "cogging": lambda u: {"cogging": 0.0},
    "hall": lambda u: {"hall_error_deg": 0.0},
    # static = dynamic friction: no Stribeck dip (a hair above: the curve divides by the gap)
    "stribeck": lambda u: {"static_friction": u.dynamic_friction * 1.0001},
    "warming": lambda u: {"warming": 0.0},
    "emf-edges": lambda u: {"emf_edge_deg": 0.5},
    "dead-time": lambda u: {"dead_time": 0.0},
    "logger-gains": lambda u: {"gains": (1.0, 1.0, 1.0), "offsets": (0.0, 0.0, 0.0)},
}


def ideal(unit: Unit, names: Iterable[str]) -> Unit:
    """``unit`` with the differences of form ``names`` (keys of :data:`IDEALS`) made ideal."""
    for name in names:
        unit = replace(unit, **IDEALS[name](unit))
    return unit


def write_unit(
    folder: Path,
    unit: Unit,
    healthy: list[Test],
    inspections: dict[str, tuple[Faults, Test]],
    motor_angle: bool = False,
) -> None:
    """A unit's rig folder: healthy recordings, inspections, the column map and the truth
    (with ``motor_angle``, the logger records the resolver angle too)."""
    folder.mkdir(parents=True, exist_ok=True)
    truth: dict = {"unit": asdict(unit), "recordings": {}}
    for j, test in enumerate(healthy):
        name = f"healthy-{j}.csv"
        write_csv(folder / name, simulate(unit, Faults(), test), motor_angle)
        truth["recordings"][name] = {"test": asdict(test), "faults": asdict(Faults())}
    for name, (faults, test) in inspections.items():
        write_csv(folder / name, simulate(unit, faults, test), motor_angle)
        truth["recordings"][name] = {"test": asdict(test), "faults": asdict(faults)}
    column_map = COLUMN_MAP + (RESOLVER_MAP if motor_angle else "")
    (folder / "logger.yaml").write_text(column_map, encoding="utf-8")
    (folder / "truth.json").write_text(json.dumps(truth, indent=2), encoding="utf-8")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    unit = spread_unit(rng)
    healthy = [Test(hinge_moment=20.0, spring=1500.0, seed=1), Test(hinge_moment=45.0, seed=2)]
    inspections = {
        "fig10.csv": (
            Faults(1.8, 4e-4, (0.2, 0.0, 0.0), 0.2, 0.0),
            Test(hinge_moment=30.0, spring=2000.0, seed=3),
        ),
        "healthy-check.csv": (Faults(), Test(hinge_moment=30.0, spring=2000.0, seed=4)),
    }
    write_unit(args.folder, unit, healthy, inspections)


if __name__ == "__main__":
    main()
