"""Monitor Model against the Reference Model: agreement, fault signatures, batch evaluator."""

from __future__ import annotations

import numpy as np
import pytest

from emaprog.config.scenario import IdentifySettings, Signals
from emaprog.faults import HEALTHY, monitor_form, values_of
from emaprog.fitting.calibration import SIGNATURE_FAULTS
from emaprog.identification.objective import Objective
from emaprog.io.storage import Trace
from emaprog.kernels.monitor import ECCENTRICITY_PAIR, SHORT_CIRCUIT_AVERAGED, short_circuit_factors
from emaprog.models.common import inputs

from .conftest import MONITOR_HEALTHY, ROOT, low_pass, monitor_run, nrmse, reference_run, scenario

FIG10 = SIGNATURE_FAULTS  # kernel form at the paper's Fig. 10 levels (RM: zeta; MM: Z = c zeta)


def test_healthy_monitor_matches_reference():
    """Figures of merit: equivalent-current NRMSE <= 5 %, position NRMSE <= 2 % (noise-free, 1 ms mean).

    The current is held to 1 %: with the commutation transients modelled it is 0.4 %."""
    ref, _ = reference_run("chirp-nominal", HEALTHY)
    mon = monitor_run("chirp-nominal", MONITOR_HEALTHY)
    assert nrmse(low_pass(mon["current"]), low_pass(ref["current"])) < 0.01
    assert nrmse(mon["position"], ref["position"]) < 0.02


def test_fig10_faulty_monitor_matches_reference(params):
    """All four faults at Fig. 10 levels: current NRMSE <= 10 % (figures of merit); held to 2 %, measured 0.6 %."""
    ref, _ = reference_run("fig10-multiple-faults")
    mon = monitor_run("fig10-multiple-faults")
    assert nrmse(low_pass(mon["current"]), low_pass(ref["current"])) < 0.02


@pytest.mark.parametrize("fault", sorted(FIG10))
def test_fault_signature_error(params, fault):
    """e_sig = ||dMM - dRM|| / ||dRM|| <= 0.35 (docs/reference.md, The models): each fault moves both models alike."""
    f = FIG10[fault]
    c = params.spec.monitor.eccentricity_gain
    ref0, _ = reference_run("chirp-nominal", HEALTHY)
    ref1, _ = reference_run("chirp-nominal", f)
    mon0 = monitor_run("chirp-nominal", MONITOR_HEALTHY)
    mon1 = monitor_run("chirp-nominal", monitor_form(values_of(f), c))
    d_ref = low_pass(ref1["current"]) - low_pass(ref0["current"])
    d_mon = low_pass(mon1["current"]) - low_pass(mon0["current"])
    e_sig = np.linalg.norm((d_mon - d_ref)[100:]) / np.linalg.norm(d_ref[100:])
    # the figure of merit is 0.35; with the commutation transients modelled all are <= 0.19 today
    assert e_sig < 0.25, e_sig


def short_circuit_signature_error(params, commutation: str) -> float:
    from emaprog.models import monitor

    opts = monitor.options(params)._replace(commutation=commutation == "transient")
    f = FIG10["short_circuit_a"]
    ref0, _ = reference_run("chirp-nominal", HEALTHY)
    ref1, _ = reference_run("chirp-nominal", f)
    inp = inputs(scenario("chirp-nominal"), params)
    mon0 = monitor.run(params, inp, MONITOR_HEALTHY, opts=opts)
    mon1 = monitor.run(params, inp, monitor_form(values_of(f), 1.0), opts=opts)
    d_ref = low_pass(ref1["current"]) - low_pass(ref0["current"])
    d_mon = low_pass(mon1["current"]) - low_pass(mon0["current"])
    return float(np.linalg.norm((d_mon - d_ref)[100:]) / np.linalg.norm(d_ref[100:]))


def test_commutation_transients_carry_the_short_circuit_signature(params):
    """A shorted phase commutes faster (L_x = N_x^2 L): modelling the outgoing phase's
    freewheeling is what makes the Monitor's PSC signature follow the Reference's
    (measured e_sig 0.25 without, 0.07 with)."""
    without = short_circuit_signature_error(params, "none")
    with_transients = short_circuit_signature_error(params, "transient")
    assert with_transients < 0.5 * without


@pytest.mark.parametrize("s6", range(6))
def test_outgoing_phase_freewheels_at_the_closed_form_rate(s6):
    """At a sector change the outgoing phase freewheels to a rail while the bridge holds the
    pair current. The complementary legs keep v_p + v_q = Vdc, so the star point sits at
    (Vdc - sum e)/3 whatever the duty and, with R = 0 and balanced phases, the outgoing
    current falls at (Vdc + 2E) / (3 L) towards zero, then stops (diode)."""
    import math

    from emaprog.kernels.bldc import IDLE_PHASE, POSITIVE_PHASE, sector
    from emaprog.kernels.monitor import commutation_step

    k, inductance, vdc, omega, held = 0.15, 2.5e-3, 270.0, 200.0, 5.0
    theta_e = s6 * math.pi / 3 - math.pi / 6 + 1e-9  # just after the sector change
    assert sector(theta_e) == s6
    sign = 1.0 if POSITIVE_PHASE[(s6 - 1) % 6] == IDLE_PHASE[s6] else -1.0
    outgoing, dt = sign * 2.0 * held, 1e-7
    pair, after, _, measured = commutation_step(
        held,
        outgoing,
        held,
        s6,
        theta_e,
        omega,
        np.full(3, k),
        np.zeros(3),
        np.full(3, inductance),
        vdc,
        dt,
        -1.0,
    )
    assert pair == pytest.approx(held, abs=1e-9)  # the regulator holds the pair current
    rate = (after - outgoing) / dt
    assert rate == pytest.approx(-sign * (vdc + 2 * k * omega) / (3 * inductance), rel=1e-6)
    # (|i_p| + |i_q| + |i_out|) / 2 with i_in = 0, i_common = -i_out: the old current
    assert abs(measured) == pytest.approx(2 * held, rel=1e-3)
    _, stopped, _, _ = commutation_step(
        held,
        sign * 1e-4,
        held,
        s6,
        theta_e,
        omega,
        np.full(3, k),
        np.zeros(3),
        np.full(3, inductance),
        vdc,
        1e-5,
        -1.0,
    )
    assert stopped == 0.0


def test_averaged_short_circuit_is_the_sector_mean_of_the_modulated_law():
    """Eq. 1-2 vs Eq. 3-4: averaged over the six sectors, both give the same gain factor."""
    n = (0.7, 1.0, 0.9)
    angles = np.linspace(0, 2 * np.pi, 6000, endpoint=False)
    modulated = np.mean([short_circuit_factors(a, *n, 0)[0] for a in angles])
    averaged = short_circuit_factors(0.3, *n, SHORT_CIRCUIT_AVERAGED)[0]
    assert modulated == pytest.approx(averaged, rel=1e-3)
    assert ECCENTRICITY_PAIR == 0


def objective_for(name: str, params):
    sc = scenario(name)
    ref, _ = reference_run(name)
    return Objective(Trace(ref), inputs(sc, params), params, IdentifySettings())


def test_batch_evaluator_equals_single_runs(params):
    objective = objective_for("fig10-multiple-faults", params)
    rng = np.random.default_rng(0)
    genes = rng.random((9, objective.dims))
    batch = objective(genes)
    singles = np.array([objective(g[None])[0] for g in genes])
    assert np.allclose(batch, singles, rtol=0, atol=1e-15)
    assert objective.evaluations == 18


def test_the_position_error_does_not_see_the_logged_positions_offset(params):
    """With the position in the error, a constant added to the recorded position (a logger
    sensor's zero) leaves every candidate's fitness as it was, while a 1 % change of its scale
    does not; the residual vector's squared sum is still the fitness.

    Tolerances: 1e-9 relative for the offset (only the rounding of a mean taken out differs);
    the scale change must move the fitness by more than 1 % (a 1 % error on a 0.05 rad chirp
    is 0.5 mrad, far above the position noise the error sees)."""
    sc = scenario("fig10-multiple-faults")
    ref, _ = reference_run("fig10-multiple-faults")
    settings = IdentifySettings(signals=Signals(current=1.0, position=1000.0, speed=0.0))

    def objective(position):
        trace = Trace({**ref, "position": position})
        return Objective(trace, inputs(sc, params), params, settings)

    base = objective(ref["position"])
    genes = np.random.default_rng(1).random((5, base.dims))
    fitness = base(genes)
    assert np.allclose(objective(ref["position"] + 2e-4)(genes), fitness, rtol=1e-9, atol=0)
    assert np.all(np.abs(objective(1.01 * ref["position"])(genes) / fitness - 1) > 0.01)
    residuals = base.residuals(genes)
    assert np.allclose((residuals**2).sum(axis=1), fitness, rtol=1e-9, atol=0)


@pytest.mark.parametrize(
    "quantity,truth,span",
    [
        ("friction", 1.8, 0.6),
        ("backlash", 4e-4, 3e-4),
        ("short_circuit_a", 0.2, 0.15),
        ("eccentricity_zeta", 0.2, 0.15),
    ],
)
def test_error_surface_has_its_minimum_at_the_truth(params, quantity, truth, span):
    """Along each fault axis through the Fig. 10 truth, the fitness is lowest near the truth.

    Tolerance: one grid step either way (the GA's target accuracy is tighter only
    because it also uses the refined local search).
    """
    from emaprog.faults import flatten

    objective = objective_for("fig10-multiple-faults", params)
    values = flatten(scenario("fig10-multiple-faults").faults)
    grid = np.linspace(truth - span, truth + span, 13)
    grid = grid[grid >= 0]
    rows = []
    for x in grid:
        v = dict(values)
        v[quantity] = float(x)
        rows.append(objective.genes_for(v))
    fitness = objective(np.array(rows))
    step = grid[1] - grid[0]
    assert abs(grid[np.argmin(fitness)] - truth) <= 1.01 * step
    assert fitness[0] > 1.5 * fitness.min() and fitness[-1] > 1.5 * fitness.min()


@pytest.mark.parametrize("indent", ["  ", ""])
def test_the_calibrated_set_records_its_change_in_the_files_own_list_style(tmp_path, indent):
    """A ``changes:`` list with its items indented or at the margin (both YAML; the second is
    what yaml.safe_dump writes) gains the calibration's record in the same style, and the
    written set loads with the calibrated values."""
    import re

    import yaml

    from emaprog.config import parameters
    from emaprog.fitting.calibration import calibrated_set

    text = (parameters.builtin_dir() / "default.yaml").read_text()
    text = re.sub(r"^  - ", indent + "- ", text, flags=re.MULTILINE)
    source = tmp_path / "mine.yaml"
    source.write_text(text)
    result = {
        "eccentricity_gain": 0.51,
        "commutation_loss": 8.0e-6,
        "r_squared": 0.999,
        "signature_error": {"friction": 0.05},
    }
    written = yaml.safe_load(calibrated_set(source, result, "2026-12-01"))
    assert written["monitor"]["eccentricity_gain"] == 0.51
    assert len(written["changes"]) == len(yaml.safe_load(text)["changes"]) + 1
    assert "emaprog calibrate" in written["changes"][-1]


def test_calibrate_finds_a_linear_z_zeta_law_and_never_edits_its_input(tmp_path):
    """Calibration (docs/reference.md): Z = c zeta with r^2 >= 0.95; every fault signature within 0.35.

    ``calibrate --parameters mine.yaml`` leaves mine.yaml byte for byte as it was
    and writes a complete set with the calibrated values that ``simulate --model
    monitor`` loads.
    """
    import json
    import shutil

    import yaml
    from typer.testing import CliRunner

    from emaprog.cli import app
    from emaprog.config import parameters

    mine = tmp_path / "mine.yaml"
    shutil.copy(parameters.builtin_dir() / "default.yaml", mine)
    before = mine.read_bytes()
    shipped = (parameters.builtin_dir() / "default.yaml").read_bytes()
    out = tmp_path / "cal"
    result = CliRunner().invoke(app, ["calibrate", "--parameters", str(mine), "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert mine.read_bytes() == before
    assert (parameters.builtin_dir() / "default.yaml").read_bytes() == shipped

    cal = json.loads((out / "calibration.json").read_text())
    assert cal["r_squared"] >= 0.95
    assert 0.4 < cal["eccentricity_gain"] < 0.6  # theory for the pair shape: 0.5
    assert 0.0 <= cal["commutation_loss"] < 2e-4
    assert max(cal["signature_error"].values()) < 0.35
    assert (out / "z_vs_zeta.png").stat().st_size > 5000

    written = parameters.load(str(out / "parameters.yaml"))
    assert written.spec.monitor.eccentricity_gain == pytest.approx(
        cal["eccentricity_gain"], abs=1e-4
    )
    assert written.spec.monitor.commutation_loss == pytest.approx(cal["commutation_loss"], rel=1e-3)
    assert "written by `emaprog calibrate`" in written.spec.changes[-1]
    scenario = yaml.safe_load((ROOT / "configs" / "chirp-nominal.yaml").read_text())
    scenario.update(parameters=str(out / "parameters.yaml"), duration=0.05)
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(scenario))
    result = CliRunner().invoke(
        app,
        [
            "simulate",
            str(tmp_path / "s.yaml"),
            "--model",
            "monitor",
            "-o",
            str(tmp_path / "t.parquet"),
        ],
    )
    assert result.exit_code == 0, result.output
    assert (tmp_path / "t.parquet").stat().st_size > 1000


def test_pair_eccentricity_law_is_the_reference_law_on_the_active_pair():
    """Flat-top pair gain k_p + k_q of the Monitor's pair law equals the Reference's
    k N_p (1 + zeta m_p) + k N_q (1 + zeta m_q) with zeta = 2 Z, shorted phase or not;
    with balanced phases it is the paper-style form 2 k (1 - Z s)."""
    import math

    from emaprog.kernels.bldc import NEGATIVE_PHASE, POSITIVE_PHASE, phase_coefficient, sector
    from emaprog.kernels.monitor import (
        eccentricity_offsets,
        eccentricity_shape,
        pair_eccentricity_coefficients,
    )

    k, z, phi = 0.15, 0.12, 0.7
    for working in (np.ones(3), np.array([0.65, 1.0, 0.9])):
        for theta_e in np.linspace(0.0, 2 * math.pi, 37):
            s6 = sector(theta_e)
            p, q = POSITIVE_PHASE[s6], NEGATIVE_PHASE[s6]
            gain = pair_eccentricity_coefficients(
                theta_e, s6, z, eccentricity_offsets(phi), working, k, np.empty(3)
            )
            reference = phase_coefficient(
                theta_e, working[p], 2 * z, phi, p, k
            ) + phase_coefficient(theta_e, working[q], 2 * z, phi, q, k)
            assert gain == pytest.approx(reference, rel=1e-12)
            if working.min() == 1.0:
                shape = eccentricity_shape(theta_e, s6, phi, ECCENTRICITY_PAIR)
                assert gain == pytest.approx(2 * k * (1 - z * shape), rel=1e-12)


def test_every_kernel_takes_at_most_twelve_named_arguments():
    """STYLE 5: kernels take named structs, a dozen arguments at most."""
    import inspect

    from emaprog.kernels import bldc, control, drive, mechanics, monitor, reference

    counted = 0
    for module in (bldc, control, drive, mechanics, monitor, reference):
        for name, func in vars(module).items():
            py_func = getattr(func, "py_func", None)
            if py_func is not None and py_func.__module__ == module.__name__:
                counted += 1
                assert len(inspect.signature(py_func).parameters) <= 12, f"{module.__name__}.{name}"
    assert counted >= 20


def test_unit_rows_vary_the_plant_per_candidate(params):
    """A candidate's unit row (inertia, viscous, friction, R, k_e, L, stiffness, hinge moment)
    gives the same fitness as the Monitor built from a parameter set with those values and
    a scenario with that constant hinge moment; a shared row equals a row per candidate."""
    from emaprog.config.parameters import ParameterFile, derive
    from emaprog.kernels.monitor import evaluate_population
    from emaprog.kernels.structs import UNIT_COLUMNS, unit_row
    from emaprog.models import monitor

    objective = objective_for("fig10-multiple-faults", params)
    genes = np.random.default_rng(3).random((3, objective.dims))
    rows = objective.kernel_rows(genes)
    changed = {
        "motor_inertia": 1.08,
        "surface_inertia": 0.9,
        "motor_viscous": 1.3,
        "static_friction": 1.1,
        "dynamic_friction": 1.05,
        "phase_resistance": 1.1,
        "back_emf_constant": 0.98,
        "phase_inductance": 0.9,
        "transmission_stiffness": 0.85,
    }
    spec = params.spec.model_dump()
    for key, factor in changed.items():
        section = (
            "electrical"
            if key in ("phase_resistance", "back_emf_constant", "phase_inductance")
            else "mechanical"
        )
        spec[section][key] *= factor
    unit = derive(ParameterFile.model_validate(spec), "in memory")
    hinge = 60.0
    row = unit_row(unit.plant, hinge)
    assert dict(zip(UNIT_COLUMNS, row))["hinge_moment"] == hinge

    def fitness(units):
        out = np.empty(rows.shape[0])
        evaluate_population(
            rows,
            units,
            objective.inputs.drive(),
            params.plant,
            objective.options,
            objective.target,
            out,
        )
        return out

    shared = fitness(row[None])
    assert np.array_equal(shared, fitness(np.tile(row, (rows.shape[0], 1))))
    assert not np.allclose(shared, objective(genes))  # the unit row does change the Monitor
    from emaprog.faults import MonitorFaults

    for j in range(rows.shape[0]):
        run = monitor.run(
            unit,
            objective.inputs,
            MonitorFaults(*rows[j]),
            opts=objective.options,
            hinge_moment=hinge,
        )
        filtered = low_pass(run["current"], objective.filter_width)
        t = objective.target
        expected = np.sum(t.sample_weight * (filtered - t.current) ** 2) / np.sum(
            t.sample_weight * t.current**2
        )
        assert shared[j] == pytest.approx(expected, rel=1e-10)
