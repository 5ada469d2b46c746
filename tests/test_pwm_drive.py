"""The PWM drive (docs/reference.md, Parameter-set YAML, ``drive``): the Reference's inverter
switch by switch against closed forms, the Monitor's closed current loop against the
Reference, and identification on a unit driven that way."""

from __future__ import annotations

import numpy as np
import pytest

from emaprog.config import parameters
from emaprog.faults import HEALTHY, flatten, monitor_form, reference_form
from emaprog.kernels.drive import L_INTEGRAL, dead_time_loss
from emaprog.kernels.reference import ENERGY_SLOTS, S_LOOP, initial_state, simulate_reference
from emaprog.kernels.structs import ReferenceOutputs
from emaprog.models import monitor, reference
from emaprog.models.common import Inputs, inputs
from emaprog.models.reference import noise

from .conftest import low_pass, nrmse, scenario
from .test_reference import energy_residual

#: The drive of the issue's example unit: 20 kHz, 1 us dead time, 1.5 kHz PI current loop.
DRIVE = {"regulator": "pwm", "pwm_frequency": 20000.0, "dead_time": 1.0e-6}


def drive_set(**drive) -> parameters.Parameters:
    """The shipped set under a PWM drive (``drive`` keys over :data:`DRIVE`)."""
    spec = parameters.load("default").spec.model_dump(mode="json")
    spec["drive"] = {**DRIVE, **drive}
    return parameters.derive(parameters.ParameterFile.model_validate(spec), "pwm-test")


@pytest.fixture(scope="module")
def pwm():
    return drive_set()


def _locked_rotor_state(params, periods=400):
    """The Reference's final state under a held position error with the rotor locked (inertias
    10^6 times larger): the speed loop demands the current limit, the rotor does not turn."""
    locked = parameters.scaled(
        params, {"motor_inertia": 1e6, "surface_inertia": 1e6}, "locked rotor"
    )
    time = np.arange(periods) * locked.controller.period
    inp = Inputs(time, np.full(periods, 0.05), np.zeros(periods), 0.0)
    out = ReferenceOutputs(*(np.empty(periods) for _ in ReferenceOutputs._fields))
    state = initial_state()
    simulate_reference(
        inp.drive(),
        noise(locked, periods, 0, False),
        locked.plant,
        HEALTHY,
        100,
        out,
        np.zeros(len(ENERGY_SLOTS)),
        state,
        0,
        periods,
    )
    return state, out


@pytest.mark.parametrize("dead_time", [0.0, 1.0e-6, 2.0e-6])
def test_dead_time_costs_its_closed_form_voltage(dead_time):
    """At a locked rotor the PI's integral settles to the pair's mean voltage: ``2 R I`` plus
    the dead time's ``2 Vdc t_d / T`` (each leg's terminal follows its diode, against the
    current, for one dead time a period): 60 V + 0, 10.8 and 21.6 V at 25 A. Tolerance 0.1 V
    (measured within 0.03 V): the explicit 1 us winding step and the ripple."""
    params = drive_set(dead_time=dead_time)
    state, out = _locked_rotor_state(params)
    e = params.spec.electrical
    assert out.current[-1] == pytest.approx(e.current_limit, abs=0.05)
    expected = 2 * e.phase_resistance * e.current_limit + 2 * e.dc_bus_voltage * dead_time * 20000
    assert state[S_LOOP + L_INTEGRAL] == pytest.approx(expected, abs=0.1)
    # the Monitor's period-mean law gives the same term far above the ripple
    assert dead_time_loss(e.current_limit, 2 * e.phase_inductance, params.electrical) == (
        pytest.approx(expected - 60.0, abs=1e-9)
    )


def test_pwm_reference_keeps_its_energy_ledger(pwm):
    """Inverter energy = losses + stored-energy change within 1.5 % (measured 0.6 %): the legs
    switch at their exact edges, the winding step is first order."""
    sc = scenario("fig10-multiple-faults")
    _, ledger = reference.run(pwm, inputs(sc, pwm), reference_form(flatten(sc.faults)), 0, False)
    assert abs(energy_residual(ledger)) < 0.015 * ledger["inverter"]


def test_monitor_follows_the_pwm_reference_and_the_hysteresis_monitor_does_not(pwm):
    """On the Fig. 10 faults the PWM Monitor's current (1 ms mean) is within 2 % RMS of the
    PWM Reference (measured 0.9-1.2 %), its speed within 0.5 % (0.2 %); the hysteresis
    Monitor on the same recording errs at least twice as much on the current."""
    sc = scenario("fig10-multiple-faults")
    faults = flatten(sc.faults)
    ref, _ = reference.run(pwm, inputs(sc, pwm), reference_form(faults), 0, False)
    truth = low_pass(ref["current"])
    errors = {}
    for name, params in (("pwm", pwm), ("hysteresis", parameters.load("default"))):
        mon = monitor.run(
            params, inputs(sc, params), monitor_form(faults, params.spec.monitor.eccentricity_gain)
        )
        errors[name] = (nrmse(low_pass(mon["current"]), truth), nrmse(mon["speed"], ref["speed"]))
    assert errors["pwm"][0] < 0.02 and errors["pwm"][1] < 0.005, errors
    assert errors["hysteresis"][0] > 2 * errors["pwm"][0], errors


def test_a_set_without_drive_and_one_naming_hysteresis_are_one_set():
    """A parameter set that does not name its drive is the hysteresis one; its provenance (and
    so every campaign hash) is as before the drive section existed."""
    base = parameters.load("default")
    spec = base.spec.model_dump(mode="json")
    spec["drive"] = {"regulator": "hysteresis"}
    named = parameters.derive(parameters.ParameterFile.model_validate(spec), "named")
    assert named.values() == base.values() and "drive" not in base.values()
    assert named.electrical == base.electrical
    assert "drive" in drive_set().values()


def test_dead_time_over_a_tenth_of_the_period_is_refused():
    with pytest.raises(ValueError, match="dead_time"):
        drive_set(pwm_frequency=60000.0, dead_time=2.0e-6)


def test_a_report_says_which_form_its_laws_were_calibrated_for():
    """The intervals' model-error laws were calibrated on the hysteresis drive with an ideal
    chain (basis ``unit``) and on PWM units logged through a chain (basis ``form``): a report
    on either says so and names the form; a hysteresis drive logged through a chain borrows
    the PWM form's laws and says they are not its own."""
    from emaprog.identification.confidence import basis_of
    from emaprog.identification.reporting import unit_form

    from .test_sensor_chain import chain_set

    plain = unit_form(parameters.load("default"))
    assert (
        plain["calibrated"] and plain["regulator"] == "hysteresis" and plain["sensor_chain"] == []
    )
    pwm = unit_form(drive_set())
    assert pwm["calibrated"] and "pwm drive" in pwm["note"]
    logged = unit_form(parameters.load("default-pwm"))
    assert "speed_source" in logged["sensor_chain"] and "calibration-pwm" in logged["note"]
    hysteresis_logged = chain_set()
    chained = unit_form(hysteresis_logged)
    assert not chained["calibrated"] and "not calibrated" in chained["note"]
    assert basis_of(False, True, parameters.load("default").hysteresis_form) == "unit"
    assert basis_of(False, True, drive_set().hysteresis_form) == "form"
    # its Monitor commutating on a recorded motor angle: the laws calibrated so
    assert basis_of(False, True, drive_set().hysteresis_form, True) == "form_angle"
    assert basis_of(False, True, parameters.load("default").hysteresis_form, True) == "unit"
    assert basis_of(False, True, hysteresis_logged.hysteresis_form) == "form"
    assert basis_of(False, False, drive_set().hysteresis_form) == "shipped"
    assert basis_of(True, True, drive_set().hysteresis_form) == "twin"


def test_a_unit_off_its_set_keeps_the_drives_gains():
    """A drive is tuned once, on its set's values: a unit spread by build tolerances (or a
    warm winding) keeps the set's PI and feed-forward gains, so its loop's crossover moves
    with its own inductance (1500 Hz x L / L' exactly), and a commissioned unit's set, whose
    winding values were fitted, loads with the gains written out instead of retuned ones."""
    base = drive_set()
    unit = parameters.scaled(
        base,
        {"phase_inductance": 1.1, "phase_resistance": 0.9, "back_emf_constant": 1.03},
        "spread unit",
    )
    e, u = base.electrical, unit.electrical
    assert (u.loop_gain, u.loop_integral, u.emf_feedforward) == (
        e.loop_gain,
        e.loop_integral,
        e.emf_feedforward,
    )
    crossover = u.loop_gain / (2.0 * u.phase_inductance) / (2.0 * np.pi)
    assert crossover == pytest.approx(1500.0 / 1.1, rel=1e-12)
    spec = parameters.fixed_drive_spec(base)
    spec["electrical"]["phase_inductance"] *= 1.2
    spec["electrical"]["back_emf_constant"] *= 0.9
    reloaded = parameters.derive(parameters.ParameterFile.model_validate(spec), "commissioned")
    assert reloaded.electrical.loop_gain == e.loop_gain
    assert reloaded.electrical.emf_feedforward == e.emf_feedforward
    written = parameters.fixed_drive_spec(parameters.load("default"))["drive"]
    assert written["regulator"] == "hysteresis" and not set(parameters.GAIN_KEYS) & set(written)


def test_the_drives_own_gains_replace_the_derived_ones():
    """Gains from the drive's configuration are used as given; a feed-forward gain on a drive
    without feed-forward is a contradiction, refused."""
    given = drive_set(proportional_gain=30.0, integral_gain=1.0e4, feedforward_gain=0.25)
    e = given.electrical
    assert (e.loop_gain, e.loop_integral, e.emf_feedforward) == (30.0, 1.0e4, 0.25)
    assert given.values()["drive"]["proportional_gain"] == 30.0
    assert "proportional_gain" not in drive_set().values()["drive"]
    with pytest.raises(ValueError, match="feedforward_gain"):
        drive_set(back_emf_feedforward=False, feedforward_gain=0.3)


def test_the_monitor_commutating_on_the_recorded_motor_angle_follows_the_current_closer(pwm):
    """A drive commutates on its own angle sensor; a Monitor on its own angle is off the
    unit's by the small differences of travel any model leaves, and each commutation it
    places apart from the unit's leaves a 1-2 A current residual. Commutating on the recorded
    motor angle, the noise-free Monitor misses the PWM Reference's current by at most 85 % of
    what it misses on its own angle, raw and as the fitness sees it (1 ms mean): measured
    75-76 % raw and 70-74 % filtered on the healthy chirp and the Fig. 10 faults; what is
    left is the commutation's integration at the Monitor's 25 us step."""
    for name in ("chirp-pwm", "fig10-multiple-faults"):
        sc = scenario(name)
        faults = flatten(sc.faults)
        ref, _ = reference.run(pwm, inputs(sc, pwm), reference_form(faults), 0, False)
        misses = {}
        for synced in (False, True):
            inp = inputs(sc, pwm)
            if synced:
                inp = inp._replace(motor_angle=np.ascontiguousarray(ref["motor_angle"]))
            mon = monitor.run(pwm, inp, monitor_form(faults, pwm.spec.monitor.eccentricity_gain))
            raw = float(np.sqrt(np.mean((mon["current"] - ref["current"]) ** 2)))
            misses[synced] = (raw, nrmse(low_pass(mon["current"]), low_pass(ref["current"])))
        assert misses[True][0] < 0.85 * misses[False][0], (name, misses)
        assert misses[True][1] < 0.85 * misses[False][1], (name, misses)


def test_the_recorded_motor_angle_reaches_the_grid_in_the_models_convention(pwm):
    """For a unit of another form: from 0 at the first recorded sample, interpolated onto
    the controller grid (a 5 kHz log onto 10 kHz: midpoints exact for a linear travel); with
    a settling lead, NaN over the lead (the Monitor commutates on its own angle there) and
    offset by the first position times the gear ratio, where the models travel to. None
    without a motor angle, and for the hysteresis form."""
    from emaprog.io.storage import Trace
    from emaprog.models.common import recorded_motor_angle

    t_rec = np.arange(11) / 5000.0
    angle = 3.0 + 40.0 * t_rec
    trace = Trace({"time": t_rec, "motor_angle": angle, "position": np.full(11, 0.01)}, {})
    grid = np.arange(21) / 10000.0
    on_grid = recorded_motor_angle(trace, t_rec, grid, 0, pwm)
    assert on_grid is not None and np.allclose(on_grid, 40.0 * grid, rtol=0, atol=1e-12)
    lead = 4
    leading = np.concatenate([(np.arange(lead) - lead) / 10000.0, grid])
    with_lead = recorded_motor_angle(trace, t_rec, leading, lead, pwm)
    assert with_lead is not None and np.isnan(with_lead[:lead]).all()
    gear = pwm.spec.mechanical.gear_ratio
    assert np.allclose(with_lead[lead:], 40.0 * grid + gear * 0.01, rtol=0, atol=1e-12)
    assert recorded_motor_angle(Trace({"time": t_rec}, {}), t_rec, grid, 0, pwm) is None
    hysteresis = parameters.load("default")  # its Monitor keeps its own commutations
    assert recorded_motor_angle(trace, t_rec, grid, 0, hysteresis) is None


def test_past_the_recorded_angles_explained_limit_the_own_angle_laws_judge(monkeypatch):
    """A commissioned PWM unit identified on its recorded motor angle takes the ``form_angle``
    laws while its fit is within their explained limit; past it (a unit whose friction law,
    cogging or back-EMF shape the calibration never held) the wider own-angle ``form`` laws
    judge it up to their own limit (docs/reference.md, Confidence), and past both it is not
    explained. One identification (a GA of 8 x 2, no polish: the fit is what it is, here
    over 100 x the floor) judged under limits set about its fit."""
    from emaprog.identification import confidence
    from emaprog.identification.run import identify_trace
    from emaprog.models.common import recorded_motor_angle

    sc = scenario("fig10-multiple-faults")
    params = parameters.load("default-pwm")
    unit = parameters.scaled(params, {"motor_inertia": 1.04}, "another unit")  # not a twin
    trace = reference.simulate(sc, unit)
    inp = inputs(sc, params)
    inp = inp._replace(motor_angle=recorded_motor_angle(trace, trace.time, inp.time, 0, params))
    ga = sc.identify.ga.model_copy(update={"population": 8, "generations": 2})
    settings = sc.identify.model_copy(update={"ga": ga, "refine": False})

    def judged(angle_limit: float, own_limit: float):
        monkeypatch.setitem(confidence.EXPLAINED_LIMIT, "form_angle", angle_limit)
        monkeypatch.setitem(confidence.EXPLAINED_LIMIT, "form", own_limit)
        result = identify_trace(
            trace, inp, params, settings, show_progress=False, commissioned=True
        )
        return result.confidence

    first = judged(1.0e9, 1.0e9)
    assert first.basis == "form_angle" and first.floor.explained
    ratio = first.floor.ratio
    past = judged(0.5 * ratio, 2.0 * ratio)
    assert past.basis == "form" and past.floor.explained and past.floor.limit == 2.0 * ratio
    assert past.floor.ratio == pytest.approx(ratio, rel=1e-12)  # the same identification
    assert (
        past.inconclusive != {f: "unexplained" for f in past.inconclusive} or not past.inconclusive
    )
    beyond = judged(0.5 * ratio, 0.7 * ratio)
    assert beyond.basis == "form" and not beyond.floor.explained
    assert len(beyond.inconclusive) == 4  # every fault, for that reason
    assert all("does not explain" in why for why in beyond.inconclusive.values())
    assert not any("does not explain" in why for why in past.inconclusive.values())
