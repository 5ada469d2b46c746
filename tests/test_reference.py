"""Reference Model physics: energy balance, friction, backlash, step response, fault directions."""

from __future__ import annotations

import numpy as np
import pytest

from emaprog.faults import HEALTHY
from emaprog.kernels.bldc import NEGATIVE_PHASE, POSITIVE_PHASE, sector
from emaprog.kernels.mechanics import borello_velocity, link_torque

from .conftest import low_pass, nrmse, reference_run


def energy_residual(ledger: dict) -> float:
    """Inverter energy minus losses minus change of stored energy [J]."""
    losses = sum(
        ledger[k] for k in ("copper", "friction", "viscous", "link_damping", "load", "end_stop")
    )
    return ledger["inverter"] - losses - (ledger["stored_final"] - ledger["stored_initial"])


def test_energy_balance_over_a_faulty_chirp():
    """Inverter energy = copper + friction + viscous + damping losses + stored-energy change.

    Every loss slot is exact to 0.1 %; the inverter slot is integrated first-order at
    the switching instants, so the residual is below 4 % at the 1 us step and
    shrinks in proportion to the step (next test).
    """
    _, e = reference_run("fig10-multiple-faults")
    assert e["copper"] > 0 and e["friction"] > 0 and e["viscous"] > 0 and e["link_damping"] > 0
    assert abs(energy_residual(e)) < 0.04 * e["inverter"]


def test_energy_residual_shrinks_with_the_time_step(params):
    from emaprog.models import reference
    from emaprog.models.common import inputs
    from emaprog.numerics import Numerics

    from .conftest import scenario

    sc = scenario("step-spring-load")
    inp = inputs(sc, params)
    residual = {}
    for substeps in (50, 400):
        _, ledger = reference.run(params, inp, HEALTHY, 0, False, Numerics(substeps, 4))
        residual[substeps] = abs(energy_residual(ledger))
    assert residual[400] < residual[50] / 5  # first order: 8x smaller step, >5x smaller residual


def test_borello_friction_hand_case():
    """Stuck stays stuck below breakaway; breaks away above it; sliding stops on reversal."""
    static, dynamic, inertia, dt = 0.12, 0.08, 1.5e-4, 1e-5
    assert borello_velocity(0.0, 0.119, static, dynamic, inertia, dt) == (0.0, -0.119)
    omega, friction = borello_velocity(0.0, 0.2, static, dynamic, inertia, dt)
    assert friction == -dynamic and omega == pytest.approx((0.2 - 0.08) / inertia * dt)
    # sliding at +0.001 rad/s with no drive decelerates at 0.08/1.5e-4 = 533 rad/s^2:
    # it would reverse within the step, so it stops exactly
    assert borello_velocity(0.001, 0.0, static, dynamic, inertia, dt)[0] == 0.0
    omega, _ = borello_velocity(1.0, 0.0, static, dynamic, inertia, dt)
    assert omega == pytest.approx(1.0 - 0.08 / inertia * dt)


def test_backlash_dead_band_transmits_no_torque(params):
    mech = params.mechanical
    n, play = mech.gear_ratio, 4e-4
    for twist in np.linspace(-0.49 * play, 0.49 * play, 11):
        assert link_torque(twist * n, 50.0, 0.0, 0.0, play, mech) == (0.0, 0.0)
    # in contact, the stiffness acts on the twist beyond half the play
    total, spring = link_torque(0.7 * play * n, 0.0, 0.0, 0.0, play, mech)
    assert total == spring == pytest.approx(mech.transmission_stiffness * 0.2 * play)
    assert link_torque(-0.7 * play * n, 0.0, 0.0, 0.0, play, mech)[0] < 0.0


def test_step_settles_without_limit_cycle(params):
    cols, _ = reference_run("step-spring-load")
    t, pos = cols["time"], cols["position"] - params.spec.sensors.position_offset
    final = t > 0.2
    assert np.max(pos) < 0.03 * 1.05  # overshoot below 5 %
    assert (
        abs(np.mean(pos[final]) - 0.03) < 3e-4
    )  # 1 % steady error (spring load, no I in position loop)
    # settled: the last 100 ms move less than 2 ADC steps; no oscillation in speed
    assert np.ptp(pos[final]) <= 2 * params.sensors.position_lsb + 1e-12
    assert np.max(np.abs(cols["speed"][final])) < 2.0


def test_same_seed_same_trace_and_noise_follows_the_seed(params):
    a, _ = reference_run("friction", noise=True)
    from emaprog.faults import flatten, reference_form
    from emaprog.models import reference
    from emaprog.models.common import inputs

    from .conftest import scenario

    sc = scenario("friction")
    again, _ = reference.run(
        params, inputs(sc, params), reference_form(flatten(sc.faults)), sc.seed
    )
    other, _ = reference.run(
        params, inputs(sc, params), reference_form(flatten(sc.faults)), sc.seed + 1
    )
    assert all(np.array_equal(a[k], again[k]) for k in a)
    assert not np.array_equal(a["current"], other["current"])


def test_healthy_fault_values_give_the_nominal_actuator():
    """Faults -> 0 is the healthy model: vanishing faults change nothing measurable."""
    nominal, _ = reference_run("chirp-nominal", HEALTHY)
    tiny, _ = reference_run(
        "chirp-nominal", HEALTHY._replace(backlash=1e-12, short_a=1e-12, eccentricity_zeta=1e-12)
    )
    assert nrmse(low_pass(tiny["current"]), low_pass(nominal["current"])) < 1e-3
    assert np.max(np.abs(tiny["position"] - nominal["position"])) < 1e-6


def test_friction_raises_the_current_needed():
    nominal, _ = reference_run("chirp-nominal", HEALTHY)
    faulty, _ = reference_run("chirp-nominal", HEALTHY._replace(friction=3.0))
    assert np.mean(np.abs(faulty["current"])) > np.mean(np.abs(nominal["current"])) + 0.1


def test_backlash_delays_the_surface(params):
    """With play the motor turns through the dead band before the surface moves."""
    nominal, _ = reference_run("step-spring-load", HEALTHY)
    faulty, _ = reference_run("step-spring-load", HEALTHY._replace(backlash=1e-3))

    def half_way(cols):
        pos = cols["position"] - params.spec.sensors.position_offset
        return cols["time"][np.argmax(pos > 0.015)]

    # at ~600 rad/s the motor crosses the 0.18 rad (motor side) of play in ~0.3 ms
    assert half_way(faulty) >= half_way(nominal) + 1e-4
    n = params.mechanical.gear_ratio
    twist = np.max(np.abs(faulty["motor_angle"] / n - faulty["position"]))
    assert twist > 0.45e-3  # the motor side travelled at least half the play ahead


def test_short_circuit_raises_ripple_where_the_faulty_phase_conducts(params):
    """Phase B shorted: current ripple grows in the four sectors where B conducts only."""
    nominal, _ = reference_run("chirp-nominal", HEALTHY)
    faulty, _ = reference_run("chirp-nominal", HEALTHY._replace(short_b=0.3))
    pp = params.electrical.pole_pairs

    def ripple_by_sector(cols):
        sectors = np.array([sector(pp * a) for a in cols["motor_angle"]])
        b_on = np.array([POSITIVE_PHASE[s] == 1 or NEGATIVE_PHASE[s] == 1 for s in sectors])
        ripple = cols["current"] - np.convolve(cols["current"], np.ones(5) / 5, "same")
        return np.std(ripple[b_on]), np.std(ripple[~b_on])

    healthy_on, healthy_off = ripple_by_sector(nominal)
    faulty_on, faulty_off = ripple_by_sector(faulty)
    assert abs(healthy_on / healthy_off - 1.0) < 0.1  # balanced motor: same ripple everywhere
    assert faulty_on > 1.2 * healthy_on
    assert abs(faulty_off / healthy_off - 1.0) < 0.1


def test_eccentricity_changes_current_but_barely_position():
    nominal, _ = reference_run("chirp-nominal", HEALTHY)
    faulty, _ = reference_run(
        "chirp-nominal", HEALTHY._replace(eccentricity_zeta=0.4, eccentricity_phase=1.0)
    )
    assert nrmse(low_pass(faulty["current"]), low_pass(nominal["current"])) > 0.01
    assert nrmse(faulty["position"], nominal["position"]) < 0.005


def test_chunked_run_behind_a_progress_bar_is_the_single_run(params, monkeypatch, capsys):
    """A long run is computed in chunks for its progress bar: same trace, same energy ledger."""
    from emaprog.faults import flatten, reference_form
    from emaprog.models import reference
    from emaprog.models.common import inputs

    from .conftest import scenario

    sc = scenario("fig10-multiple-faults")
    whole, ledger = reference_run("fig10-multiple-faults", noise=True)
    monkeypatch.setattr(reference, "PROGRESS_STEPS", 1)  # every run counts as long
    chunked, chunked_ledger = reference.run(
        params, inputs(sc, params), reference_form(flatten(sc.faults)), sc.seed, show_progress=True
    )
    assert all(np.array_equal(whole[k], chunked[k]) for k in whole)
    assert chunked_ledger == pytest.approx(ledger, rel=1e-12, abs=1e-15)
    log = capsys.readouterr().err  # not a terminal: plain progress lines
    assert "reference model: 5000/5000" in log
