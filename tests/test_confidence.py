"""Confidence of an identification: the noise floor and the linearised covariance against
closed forms, "inconclusive" for recordings that cannot tell, and the correction choice."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from emaprog.cli import app
from emaprog.config import parameters
from emaprog.config.scenario import Scenario, load_scenario
from emaprog.identification.confidence import (
    correlation_length,
    covariance,
    information_inverse,
    is_twin,
    noise_sigma,
    quantity_error,
    quantity_interval,
    widened,
)
from emaprog.identification.objective import (
    Correction,
    ResidualRecording,
    recording_correction,
)
from emaprog.io.storage import Trace, write_trace
from emaprog.models import reference

from .conftest import CONFIGS


def test_noise_sigma_reads_white_noise_under_a_moving_signal():
    """A 10 Hz, 0.05 rad chirp-like sine at 10 kHz with white noise of 1e-4 rad: the
    second-difference estimate finds sigma within 5 % (2 % sampling error of a MAD over
    5000 samples, x2 margin); the signal itself adds < 1e-6 rad per second difference."""
    rng = np.random.default_rng(3)
    t = np.arange(5000) / 1e4
    x = 0.05 * np.sin(2 * np.pi * 10 * t) + rng.normal(0.0, 1e-4, t.size)
    assert noise_sigma(x, 0.0) == pytest.approx(1e-4, rel=0.05)
    # a quantised constant has no noise but its rounding: lsb / sqrt(12)
    assert noise_sigma(np.full(100, 0.3), 1e-3) == pytest.approx(1e-3 / math.sqrt(12.0))


def test_correlation_length_of_a_moving_average_is_its_width():
    """White noise averaged over w samples has integrated autocorrelation time w
    (1 + 2 sum_{k<w} (1 - k/w) = w); measured over 200 000 samples within 5 %."""
    rng = np.random.default_rng(4)
    width = 10
    x = np.convolve(rng.normal(size=200_000), np.ones(width) / width, mode="valid")
    assert correlation_length(x, [x.size]) == pytest.approx(width, rel=0.05)
    assert correlation_length(rng.normal(size=50_000), [50_000]) == pytest.approx(1.0, abs=0.05)


def test_sandwich_covariance_is_ordinary_least_squares_for_white_noise():
    """y = J theta + e, e white with sigma 0.1: the covariance of the least-squares estimate
    is sigma^2 (J^T J)^-1. From the residual of one realisation (two equal blocks), within
    10 % on the diagonal (the variance estimate's 2 % sampling error, and the blocks'
    correlation lengths of about 1 each estimated within a few %)."""
    rng = np.random.default_rng(5)
    jac = rng.normal(size=(4000, 3))
    theta = np.array([1.0, -2.0, 0.5])
    y = jac @ theta + rng.normal(0.0, 0.1, 4000)
    estimate, *_ = np.linalg.lstsq(jac, y, rcond=None)
    residual = jac @ estimate - y
    cov = covariance(jac, residual, [2000, 2000])
    expected = 0.01 * np.linalg.inv(jac.T @ jac)
    assert np.diag(cov) == pytest.approx(np.diag(expected), rel=0.10)


def test_a_parameter_that_changes_nothing_gets_infinite_variance():
    jac = np.column_stack([np.linspace(0, 1, 50), np.zeros(50)])
    cov = information_inverse(jac.T @ jac)
    assert math.isfinite(cov[0, 0]) and cov[1, 1] == math.inf


def _trace(command: np.ndarray, rate: float = 1e4) -> Trace:
    n = command.size
    time = np.arange(n) / rate
    return Trace(
        {
            "time": time,
            "command": command,
            "position": command,
            "speed": np.zeros(n),
            "current": np.zeros(n),
        },
        {},
    )


def test_twin_factors_only_for_the_reference_run_with_the_very_same_values(params):
    """A Reference trace identified with the set that made it is a twin experiment; the
    same trace against a unit 5 % off in inertia, or a rig recording's metadata, is not,
    and gets the (wider, for friction) unit factors."""
    sc = Scenario.model_validate(
        {**load_scenario(CONFIGS / "chirp-nominal.yaml").model_dump(), "duration": 0.05}
    )
    trace = reference.simulate(sc, params)
    assert is_twin(trace, params)
    other = parameters.scaled(params, {"motor_inertia": 1.05}, "a unit off the set")
    assert not is_twin(trace, other)
    rig = Trace(trace.columns, {**trace.metadata, "model": "recording"})
    assert not is_twin(rig, params) and not is_twin(Trace(trace.columns, None), params)
    assert (
        quantity_error("friction", "twin").factor
        < quantity_error("friction").factor
        < quantity_error("friction", "shipped").factor
    )
    # a nuisance has one law, whatever the basis
    assert (
        quantity_error("hinge_moment")
        == quantity_error("hinge_moment", "twin")
        == quantity_error("hinge_moment", "shipped")
    )


def test_zeta_interval_of_a_healthy_rotor_covers_zero_90_percent_of_the_time():
    """The length of a 2-D normal estimate around zeta = 0 is Rayleigh: a plain
    estimate +- 1.645 sigma interval holds 0 only when |z| <= 1.645 sigma, 1 - exp(-1.645^2/2)
    = 74 % of draws; the Rayleigh rule holds it in 90 % (20 000 draws: sampling error 0.2 %,
    tolerance 1 %). A clear eccentricity keeps the symmetric interval, and other
    quantities are only clipped to their range."""
    rng = np.random.default_rng(1)
    sigma = 0.004
    zeta = np.hypot(*rng.normal(0.0, sigma, (2, 20000)))
    low, high = quantity_interval("eccentricity_zeta", zeta, np.full(zeta.size, sigma))
    assert np.mean((low <= 0.0) & (high >= 0.0)) == pytest.approx(0.90, abs=0.01)
    assert np.mean(zeta <= 1.645 * sigma) == pytest.approx(0.742, abs=0.01)
    assert quantity_interval("eccentricity_zeta", 0.2, sigma) == pytest.approx(
        (0.2 - 1.645 * sigma, 0.2 + 1.645 * sigma), rel=1e-4
    )
    assert quantity_interval("short_circuit_a", 0.004, sigma) == pytest.approx(
        (0.0, 0.004 + 1.6448536 * sigma)
    )


def test_model_error_law_adds_the_signature_share_in_quadrature():
    """sqrt((f sigma)^2 + (s d)^2): 3-4-5 with f = 1.5, sigma = 2, s = 0.1, d = 40; a
    healthy estimate (d = 0) keeps f sigma; an unbounded sigma stays unbounded."""
    from emaprog.faults import ModelError

    assert widened(ModelError(1.5, 0.1), 2.0, 40.0) == pytest.approx(5.0)
    assert widened(ModelError(1.5, 0.1), 2.0, 0.0) == pytest.approx(3.0)
    assert widened(ModelError(1.5, 0.1), math.inf, 1.0) == math.inf
    # the load term adds in quadrature too: sqrt(3^2 + 4^2 + (0.5 x 24)^2) = 13
    assert widened(ModelError(1.5, 0.1, 0.5), 2.0, 40.0, 24.0) == pytest.approx(13.0)


def test_fault_load_counts_each_fault_in_incipient_thresholds():
    """0 when healthy; a fault at its incipient threshold adds 1 (friction by |k_f - 1|, the
    worst phase's fraction, zeta, never the eccentricity's angle); arrays work elementwise."""
    from emaprog.config import parameters
    from emaprog.faults import CATALOGUE, fault_load, healthy_values

    health = parameters.load("default").spec.health
    incipient = {f.name: getattr(health, f.name).incipient for f in CATALOGUE}
    assert fault_load(healthy_values(), incipient) == 0.0
    values = {
        **healthy_values(),
        "friction": 1.0 - incipient["friction"],
        "short_circuit_b": 2.0 * incipient["short_circuit"],
        "short_circuit_c": incipient["short_circuit"],
        "eccentricity_phase": 3.0,
    }
    assert fault_load(values, incipient) == pytest.approx(3.0)
    arrays = {k: np.array([v, healthy_values()[k]]) for k, v in values.items()}
    assert fault_load(arrays, incipient) == pytest.approx([3.0, 0.0])


def test_recording_correction_needs_the_same_command_on_the_same_grid():
    """The commissioning residual is subtracted only from a trace that repeats its
    command on its sample grid; otherwise the reason is given (and `reference` applies)."""
    command = 0.05 * np.sin(np.linspace(0, 20, 1000))
    residual = {name: np.full(1000, 0.1) for name in ("current", "position", "speed")}
    recording = ResidualRecording("healthy.parquet", np.arange(1000) / 1e4, command, residual)
    applied = recording_correction(_trace(command), recording)
    assert isinstance(applied, Correction) and applied.applied == "recording"
    assert "healthy.parquet" in recording_correction(_trace(command[:900]), recording)
    assert "command" in recording_correction(_trace(1.1 * command), recording)
    assert "grid" in recording_correction(_trace(command, rate=5e3), recording)


def test_the_recording_correction_is_the_mean_of_the_commissioning_recordings_repeated():
    """Of a unit's commissioning recordings, those whose command and grid the inspection
    repeats are averaged (each residual is the form error under its own load plus its own
    noise); one on another command is left out, and with none repeated `reference` applies
    and says why."""
    from emaprog.identification.run import choose_correction
    from emaprog.models.common import inputs

    params = parameters.load("default")
    scenario = load_scenario(CONFIGS / "chirp-nominal.yaml")
    inp = inputs(scenario, params)
    time = inp.time - inp.time[0]
    command = np.asarray(inp.command, float)
    settings = scenario.identify.model_copy(update={"nominal_correction": "recording"})

    def recording(name: str, level: float, repeated: bool = True) -> ResidualRecording:
        residual = {s: np.full(time.size, level) for s in ("current", "position", "speed")}
        return ResidualRecording(name, time, command if repeated else 1.1 * command, residual)

    trace = _trace(command, rate=1.0 / (time[1] - time[0]))
    both = choose_correction(
        trace, inp, params, settings, recordings=[recording("a.csv", 0.1), recording("b.csv", 0.3)]
    )
    assert both.applied == "recording" and "a.csv" in both.note and "b.csv" in both.note
    assert both.signals is not None and np.allclose(both.signals["current"], 0.2, rtol=1e-12)
    other = recording("c.csv", 0.5, repeated=False)
    one = choose_correction(
        trace, inp, params, settings, recordings=[recording("a.csv", 0.1), other]
    )
    assert one.signals is not None and np.allclose(one.signals["speed"], 0.1, rtol=1e-12)
    assert "c.csv" not in one.note
    none = choose_correction(trace, inp, params, settings, recordings=[other])
    assert none.applied == "reference" and "c.csv" in none.note


@pytest.mark.slow
@pytest.mark.parametrize(
    "command",
    [
        {"kind": "constant", "offset": 0.0},  # the actuator at rest
        {"kind": "chirp", "amplitude": 2.0e-5, "start_frequency": 0.5, "end_frequency": 10.0},
    ],
)
def test_a_recording_that_cannot_tell_is_inconclusive_for_every_fault(tmp_path, command):
    """At rest (command 0, current ~ 0) or a command too small to move the motor past its
    friction (2e-5 rad): exit 0, every verdict `inconclusive` with its reason, no fault
    flagged, no short-circuit phase named as a finding; the report still has its intervals."""
    data = load_scenario(CONFIGS / "fig10-multiple-faults.yaml").model_dump(mode="json")
    data.update(name="cannot-tell", command=command)
    trace = tmp_path / "trace.parquet"
    write_trace(
        trace, reference.simulate(Scenario.model_validate(data), parameters.load("default"))
    )
    result = CliRunner().invoke(app, ["identify", str(trace), "-o", str(tmp_path / "r")])
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    assert set(report["health"].values()) == {"inconclusive"}
    assert set(report["confidence"]["inconclusive"]) == set(report["health"])
    assert "inconclusive" in result.output and "on phase" not in result.output
    assert report["interval"]["friction"] is not None


def test_every_polar_fault_gets_its_own_plane_and_its_own_errors():
    """A catalogue with two polar faults (the eccentricity and a copy of it named
    ``wobble``): each gets a plane, a point maps back to both magnitudes and angles, and
    each magnitude's error is its own plane's radial one (the covariance is diagonal in
    the planes, so along the estimate it is the coordinate's, exactly: tolerance 1e-12)."""
    from types import SimpleNamespace

    from emaprog.faults import FAULTS
    from emaprog.identification.confidence import (
        _coordinates,
        _planes,
        _polar_errors,
        _values,
    )
    from emaprog.identification.objective import Gene

    ecc = FAULTS["eccentricity"]
    wobble = ecc._replace(
        name="wobble",
        quantities=tuple(
            q._replace(name=q.name.replace("eccentricity", "wobble")) for q in ecc.quantities
        ),
    )
    planes = _planes((FAULTS["friction"], ecc, wobble))
    assert [p.fault for p in planes] == ["eccentricity", "wobble"]
    values = {
        "friction": 1.5,
        "eccentricity_zeta": 0.2,
        "eccentricity_phase": 0.5,
        "wobble_zeta": 0.1,
        "wobble_phase": 2.0,
    }
    genes = [
        Gene("friction", 1.0, 3.0, False),
        Gene("eccentricity_zeta", 0.0, 0.8, False),
        Gene("eccentricity_phase", 0.0, 2 * math.pi, True),
        Gene("wobble_zeta", 0.0, 0.8, False),
        Gene("wobble_phase", 0.0, 2 * math.pi, True),
    ]
    objective = SimpleNamespace(genes=genes, params=SimpleNamespace(hysteresis_form=True))
    coords, point = _coordinates(objective, values, planes)
    assert [c.name for c in coords] == [
        "friction",
        "eccentricity_x",
        "eccentricity_y",
        "wobble_x",
        "wobble_y",
    ]
    back = _values({}, point, planes)
    assert all(back[k] == pytest.approx(v, abs=1e-12) for k, v in values.items())
    variances = np.array([1e-4, 4e-4, 9e-4, 1e-2, 1e-2])
    # eccentricity at 0.5 rad: along the estimate the x/y variances mix by cos^2 / sin^2
    errors = _polar_errors(coords, np.diag(variances), values, planes)
    c, s = math.cos(0.5), math.sin(0.5)
    assert errors["eccentricity_zeta"] == pytest.approx(
        math.sqrt(4e-4 * c * c + 9e-4 * s * s), rel=1e-12
    )
    assert errors["wobble_zeta"] == pytest.approx(0.1, rel=1e-12)  # isotropic: the same
    assert errors["wobble_phase"] == pytest.approx(0.1 / 0.1, rel=1e-12)  # across / zeta


def test_the_jacobian_on_another_form_is_the_slope_over_its_span():
    """On a Monitor of another form (PWM drive, logger chain) the residual is a staircase in
    the parameters (docs/reference.md, Confidence: ``FORM_STEP_SHARE``): the Jacobian takes
    its differences over a twentieth of each span, and there its columns are the slope, the
    secant over twice the step agreeing within 20 % (measured 4-14 % on the friction, the
    shorts and the eccentricity at a healthy unit; over a tenth of the step the secants read
    1.2-3.5 times it, the jumps); a hysteresis unit keeps the fine step."""
    from types import SimpleNamespace

    from emaprog.identification.confidence import (
        FORM_STEP_SHARE,
        STEP_SHARE,
        _coordinates,
        _values,
        jacobian,
    )
    from emaprog.identification.objective import Objective, fine_plant
    from emaprog.models.common import inputs

    sc = load_scenario(CONFIGS / "chirp-pwm.yaml")
    params = parameters.load("default-pwm")
    assert not params.hysteresis_form and parameters.load("default").hysteresis_form
    objective = Objective(reference.simulate(sc, params), inputs(sc, params), params, sc.identify)
    values = objective.values(objective.healthy_genes())
    coords, jac = jacobian(objective, values)
    _, point = _coordinates(objective, values)
    spans = {g.quantity: g.upper - g.lower for g in objective.genes}
    assert coords[0].step == pytest.approx(FORM_STEP_SHARE * spans[coords[0].name])
    hysteresis = SimpleNamespace(genes=objective.genes, params=parameters.load("default"))
    fine, _ = _coordinates(hysteresis, values)
    assert fine[0].step == pytest.approx(STEP_SHARE * spans[fine[0].name])
    checked = 0
    for k, c in enumerate(coords):
        if c.name == "backlash":  # a dead zone: not linear from 0, by nature
            continue
        up = min(point[c.name] + 2 * c.step, c.upper)
        down = max(point[c.name] - 2 * c.step, c.lower)
        rows = [objective.genes_for(_values(values, {**point, c.name: x})) for x in (up, down)]
        moved = objective.residuals(np.array(rows), fine_plant(params.plant))
        secant = float(np.linalg.norm(moved[0] - moved[1])) / (up - down)
        assert float(np.linalg.norm(jac[:, k])) == pytest.approx(secant, rel=0.2), c.name
        checked += 1
    assert checked >= 6  # friction, three shorts, the eccentricity's plane


@pytest.mark.parametrize(
    ("estimate", "interval", "unit", "form"),
    [
        (1.2, (1.10, 1.30), None, "does not clear it"),  # clear of healthy, not of incipient
        (1.2, (1.16, 1.30), None, None),  # the whole interval at or above incipient (0.15)
        (1.2, (0.95, 1.30), "cannot tell", "cannot tell"),  # holds healthy, reaches incipient
        (1.05, (0.97, 1.10), None, None),  # below incipient throughout: nominal on both
    ],
)
def test_a_finding_on_another_form_needs_its_whole_interval_past_incipient(
    estimate, interval, unit, form
):
    """Friction at incipient 0.15: on a unit's own hysteresis set the estimate decides once
    its interval is clear of healthy; on the form basis (another form: errors of the
    thresholds' size) a finding's interval must clear the threshold."""
    from emaprog.identification.confidence import interval_verdict

    values = {"friction": estimate}
    for basis, expected in (("unit", unit), ("form", form)):
        why = interval_verdict("friction", values, {"friction": interval}, 0.15, basis)
        assert (why is None) if expected is None else (expected in why), (basis, why)
