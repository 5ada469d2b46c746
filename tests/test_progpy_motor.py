"""Independent check of the Reference motor against NASA ProgPy's three-phase BLDC.

ProgPy's ``DCMotor`` (``progpy.models``, written by NASA's SWS project, not here)
is a three-phase trapezoidal BLDC: per phase ``L di/dt = v - R i - K F(theta) w``,
``J dw/dt = K sum F i - B w - t_l``, ``dtheta/dt = (Po/2) w``, explicit Euler.
Its inputs ``v_a, v_b, v_c`` are phase-to-neutral voltages with the neutral held
at 0 V (a four-wire machine). The Reference Model's motor is star connected
with a floating neutral (``sum i = 0``); the same machine is obtained from
ProgPy by applying the star point's potential to its inputs, computed from
ProgPy's *own* state at each step: ``v_x = u_x - mean(u) + mean(e)`` for
terminal voltages ``u`` (balanced R, L). Both models then run the same
open-loop terminal voltages (a V/f ramp that spins the rotor synchronously)
and load torque, and their currents, speed and angle are compared.

What the comparison checks: the back-EMF shape (trapezoid, 120 deg flat top,
60 deg ramps), the phase sequence and angle convention (ProgPy's phase b is our
C, its c our B, and its angle lags ours by pi/6 electrical: asserted on the
shapes alone below), the star-point winding equations of
:func:`emaprog.kernels.bldc.star_rates` and the torque sum.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

progpy_models = pytest.importorskip("progpy.models", reason="progpy is a test extra")

from emaprog.kernels.bldc import PHASE_OFFSET, phase_coefficient, star_rates, trapezoid  # noqa: E402

#: ProgPy's electrical angle is ours minus pi/6; its phases (a, b, c) are our (A, C, B).
ANGLE_SHIFT = -math.pi / 6.0
PROGPY_PHASE = (0, 2, 1)  # our phase x is ProgPy's phase PROGPY_PHASE[x]


def test_back_emf_shapes_map_onto_progpy():
    """Our trapezoids are ProgPy's ``backemf`` with the phase and angle mapping above (exact)."""
    from progpy.models.dcmotor import backemf

    for theta in np.linspace(0.0, 2.0 * math.pi, 721, endpoint=False):
        theirs = backemf(float((theta + ANGLE_SHIFT) % (2.0 * math.pi)))
        ours = [trapezoid(theta + PHASE_OFFSET[x]) for x in range(3)]
        for x in range(3):
            assert ours[x] == pytest.approx(theirs[PROGPY_PHASE[x]], abs=1e-9)


def _drive(t: float) -> tuple[np.ndarray, float]:
    """Terminal voltages [V] of a V/f ramp (our phase order) and the load torque [N m]."""
    ramp = 0.04  # [s] electrical speed ramps 0 -> 1200 rad/s, then holds
    w_e = 1200.0 * min(t / ramp, 1.0)
    angle = 0.5 * 1200.0 / ramp * t * t if t < ramp else 0.5 * 1200.0 * ramp + w_e * (t - ramp)
    amplitude = 20.0 + 0.15 * w_e / 4.0 * 1.1  # [V] boost + back-EMF at synchronous speed
    u = np.array([amplitude * math.sin(angle + PHASE_OFFSET[x]) for x in range(3)])
    return u, 0.05 if t > 0.02 else 0.0


def test_reference_motor_matches_progpy_dcmotor(params):
    """Same open-loop drive and load: currents, speed and angle agree to 1e-6 of their scale.

    Tolerance: both integrate the same equations with explicit Euler at the same
    1 us step from the same state, so only rounding separates them (the
    arithmetic is ordered differently); 1e-6 of the peak leaves room for its
    growth through the loop over 60 000 steps, while a wrong shape, offset,
    phase order or neutral would differ at the percent level at once.
    """
    e = params.spec.electrical
    m = params.spec.mechanical
    pp = e.pole_pairs
    motor = progpy_models.DCMotor(
        L=e.phase_inductance,
        M=0.0,
        R=e.phase_resistance,
        K=e.back_emf_constant,
        B=m.motor_viscous,
        Po=2 * pp,
        J=m.motor_inertia,
    )
    dt, steps = 1e-6, 60_000
    x = motor.initialize()
    x["theta"] = ANGLE_SHIFT  # both rotors at our electrical angle 0

    i = np.zeros(3)
    omega, theta_m = 0.0, 0.0
    r = np.full(3, e.phase_resistance)
    inductance = np.full(3, e.phase_inductance)
    tied = np.ones(3, dtype=np.int64)
    back_emf = np.zeros(3)
    ours = np.empty((steps, 5))
    theirs = np.empty((steps, 5))
    for k in range(steps):
        u, load = _drive(k * dt)
        # ProgPy: star point from its own state
        shapes = [trapezoid(float(x["theta"]) - ANGLE_SHIFT + PHASE_OFFSET[p]) for p in range(3)]
        emf_theirs = np.array(
            [e.back_emf_constant * shapes[p] * float(x["v_rot"]) for p in range(3)]
        )
        phase_v = u - u.mean() + emf_theirs.mean()
        inputs = {f"v_{'abc'[PROGPY_PHASE[p]]}": float(phase_v[p]) for p in range(3)}
        x = motor.next_state(x, motor.InputContainer({**inputs, "t_l": load}), dt)
        theirs[k] = (
            float(x["i_a"]),
            float(x["i_c"]),
            float(x["i_b"]),
            float(x["v_rot"]),
            (float(x["theta"]) - ANGLE_SHIFT) % (2.0 * math.pi),
        )

        # ours: the Reference kernel's phase coefficient, shape, star rates and torque sum
        theta_e = pp * theta_m
        torque = 0.0
        for p in range(3):
            shape = phase_coefficient(theta_e, 1.0, 0.0, 0.0, p, e.back_emf_constant) * trapezoid(
                theta_e + PHASE_OFFSET[p]
            )
            back_emf[p] = shape * omega
            torque += shape * i[p]
        rates = star_rates(u, tied, i, back_emf, r, inductance, e.dc_bus_voltage)
        i += np.array(rates[:3]) * dt
        omega, theta_m = (
            omega + (torque - m.motor_viscous * omega - load) / m.motor_inertia * dt,
            theta_m + omega * dt,
        )
        ours[k] = (i[0], i[1], i[2], omega, (pp * theta_m) % (2.0 * math.pi))

    scale_i = np.abs(theirs[:, :3]).max()
    scale_w = np.abs(theirs[:, 3]).max()
    assert scale_i > 1.0 and scale_w > 200.0  # the rotor really spins and carries current
    assert np.abs(ours[:, :3] - theirs[:, :3]).max() < 1e-6 * scale_i
    assert np.abs(ours[:, 3] - theirs[:, 3]).max() < 1e-6 * scale_w
    angle_gap = np.abs(np.remainder(ours[:, 4] - theirs[:, 4] + math.pi, 2 * math.pi) - math.pi)
    assert angle_gap.max() < 1e-6
