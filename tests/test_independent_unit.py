"""emaprog against a unit it did not write: the independently written actuator simulator of
``benchmarks/independent_unit.py`` (its own equations: a switched inverter, LuGre friction,
rounded back-EMF, a logger chain, a European CSV), and the rig defaults it measured."""

from __future__ import annotations

import ast
import sys
from dataclasses import replace

import numpy as np
import pytest

from emaprog.config import parameters
from emaprog.config.parameters import ParameterFile, derive
from emaprog.config.scenario import IdentifySettings
from emaprog.identification.defaults import resolve
from emaprog.io.recordings import load_column_map, read_recording

from .conftest import ROOT

sys.path.insert(0, str(ROOT / "benchmarks"))
import independent_unit as iu  # noqa: E402


def test_the_simulator_takes_nothing_from_emaprog():
    """The simulator is a check from outside only while it shares no code with emaprog."""
    tree = ast.parse((ROOT / "benchmarks" / "independent_unit.py").read_text())
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            imported.add((node.module or "").split(".")[0])
    assert "emaprog" not in imported, imported


@pytest.fixture(scope="module")
def held_unit(tmp_path_factory):
    """A healthy unit held 0.15 s under 30 N m and a 2000 N m/rad spring before its logger
    starts (as on a rig), written as its logger's European CSV and read back by emaprog."""
    folder = tmp_path_factory.mktemp("independent")
    rec = iu.simulate(iu.Unit(), iu.Faults(), iu.Test(hinge_moment=30.0, spring=2000.0, seed=4))
    iu.write_csv(folder / "held.csv", rec)
    (folder / "logger.yaml").write_text(iu.COLUMN_MAP)
    params = parameters.load("default-pwm")
    trace = read_recording(
        folder / "held.csv", load_column_map(folder / "logger.yaml"), params, folder / "logger.yaml"
    )
    return rec, trace, params


def test_the_equivalent_current_of_a_unit_held_under_load_is_signed_like_its_torque(held_unit):
    """The replayed controller starts with the integrator the unit already held: the signed
    equivalent current follows the true torque's sign wherever the current stands clear of
    its noise (0.05 A per channel on this logger: 4 sigma = 0.2 A; measured 0 wrong there,
    against 4.4 % of all samples wrong with an empty integrator). The charge found is the
    holding current: the true torque at the first sample over the pair's torque constant
    2 k_e, within 0.1 A (the logger's noise and offsets, and a rounded back-EMF whose pair
    constant is a few % under 2 k_e)."""
    rec, trace, params = held_unit
    current = trace.columns["current"]
    torque = rec["true_torque"][: current.size]
    clear = np.abs(current) > 0.2
    wrong = np.sign(current[clear]) != np.sign(torque[clear])
    assert wrong.mean() <= 0.002, wrong.mean()
    charge = trace.metadata["integrator_charge"]
    assert f"{charge:.3f} A" in trace.metadata["equivalent_current"]
    holding = torque[0] / (2.0 * params.spec.electrical.back_emf_constant)
    assert abs(charge - holding) <= 0.1, (charge, holding)


def test_an_empty_integrator_would_sign_it_wrongly(held_unit):
    """The control: the same recording signed by the replay from empty integrators is wrong
    on more than 3 % of the samples clear of the noise (what the charge removes)."""
    from emaprog.io.recordings import current_demand

    rec, trace, params = held_unit
    c = trace.columns
    demand = current_demand(c["time"], c["command"], c["position"], c["speed"], params)
    torque = rec["true_torque"][: demand.size]
    clear = np.abs(c["current"]) > 0.2
    wrong = np.sign(demand[clear]) != np.sign(torque[clear])
    assert wrong.mean() > 0.03, wrong.mean()


def _with_commissioned_spring(spring: float):
    """The shipped hysteresis set with a commissioning record of one recording whose spring
    was ``spring`` [N m/rad]."""
    spec = parameters.load("default").spec.model_dump()
    spec["commissioning"] = {
        "date": "2026-12-06",
        "emaprog_version": "test",
        "base": "default",
        "recordings": [
            {
                "file": "healthy.csv",
                "sha256": "0" * 64,
                "hinge_moment": 20.0,
                "hinge_moment_standard_error": 1.0,
                "hinge_stiffness": spring,
                "residual": {"current": 0.01},
            }
        ],
        "fitted": {},
        "not_determined": [],
        "degenerate": [],
        "residual": 0.01,
    }
    return derive(ParameterFile.model_validate(spec), "unit.yaml")


def test_a_real_unit_that_met_a_spring_estimates_it_by_default():
    """`identify.nuisances` omitted on a real unit: the aerodynamic spring joins the hinge
    moment and the winding resistance where the unit's commissioning found one or its set is
    of another form (the form laws were calibrated with it estimated); a unit of the paper's
    form commissioned without one keeps the two (the example rig's documented figures); a
    twin adds none; `--nuisances` is taken at its word."""
    recording = {"model": "recording"}
    open_settings = IdentifySettings()
    two = ["hinge_moment", "resistance_factor"]
    three = [*two, "hinge_stiffness"]
    plain = resolve(open_settings, recording, _with_commissioned_spring(0.0))
    assert plain.settings.nuisances == two
    sprung = resolve(open_settings, recording, _with_commissioned_spring(1445.0))
    assert sprung.settings.nuisances == three
    assert "commissioning found an aerodynamic spring" in sprung.notes["nuisances"]
    form = resolve(open_settings, recording, parameters.load("default-pwm"))
    assert form.settings.nuisances == three
    assert "another form" in form.notes["nuisances"]
    twin = resolve(open_settings, {"model": "reference"}, parameters.load("default-pwm"))
    assert twin.settings.nuisances == []
    named = resolve(open_settings, recording, parameters.load("default-pwm"), nuisances=two)
    assert named.settings.nuisances == two


def test_a_rotor_off_its_sensors_zero_is_located(tmp_path):
    """The simulator's rotor electrical zero 70 degrees from the position sensor's, and its
    phase sequence the models' mirrored (its phase B lags where the models' leads): emaprog's
    phase identity trusts the match and finds the rotor at 70 degrees up to the cyclic
    relabelling of the windings (a rotor 120 degrees on is the same as the windings named
    one on, and the report names them back as the logger does), within 10 degrees: the
    transmission's twist under 30 N m, which a rotor angle from the surface position cannot
    see, is 3-4 degrees electrical here, and the speed's filter lag adds as much."""
    unit = replace(iu.Unit(), electrical_zero_deg=70.0)
    rec = iu.simulate(unit, iu.Faults(), iu.Test(hinge_moment=30.0, seed=5))
    iu.write_csv(tmp_path / "rotor.csv", rec)
    (tmp_path / "logger.yaml").write_text(iu.COLUMN_MAP)
    trace = read_recording(
        tmp_path / "rotor.csv",
        load_column_map(tmp_path / "logger.yaml"),
        parameters.load("default-pwm"),
        tmp_path / "logger.yaml",
    )
    identity = trace.metadata["phase_identity"]
    assert identity["trusted"], identity
    off = (identity["electrical_angle_deg"] - 70.0) % 120.0
    assert min(off, 120.0 - off) <= 10.0, identity
    # mirrored sequence: one pair of channels swapped against the map's names
    swapped = [w for w, key in identity["windings"].items() if key != f"current_{w}"]
    assert len(swapped) == 2, identity


def test_a_set_whose_controller_is_not_the_units_is_refused(tmp_path):
    """The same unit with its position gain 20 % under the set's: the set's controller
    replayed on the recording misses the phase currents by about twice their RMS (measured
    2.05; against 0.05 with the set's gains) and would sign 40 % of the samples wrongly, so
    the recording is refused before any fit, naming the set's controller (exit 2 from the
    command line); the unit whose gains are the set's passes."""
    from emaprog.errors import InputError
    from emaprog.io.recordings import check_plausible

    (tmp_path / "logger.yaml").write_text(iu.COLUMN_MAP)
    params = parameters.load("default-pwm")
    misfits = {}
    for name, gain in (("matched", 10800.0), ("slower", 8640.0)):
        rec = iu.simulate(
            replace(iu.Unit(), position_gain=gain),
            iu.Faults(),
            iu.Test(hinge_moment=20.0, spring=1500.0, seed=1),
        )
        iu.write_csv(tmp_path / f"{name}.csv", rec)
        trace = read_recording(
            tmp_path / f"{name}.csv",
            load_column_map(tmp_path / "logger.yaml"),
            params,
            tmp_path / "logger.yaml",
        )
        misfits[name] = trace.metadata["demand_misfit"]
        if name == "matched":
            check_plausible(trace, params, tmp_path / f"{name}.csv")
        else:
            with pytest.raises(InputError) as refused:
                check_plausible(trace, params, tmp_path / f"{name}.csv")
            assert refused.value.key == "controller"
            assert "position_gain" in str(refused.value)
    assert misfits["matched"] < 0.1 and misfits["slower"] > 1.5, misfits


def test_making_a_difference_ideal_changes_that_difference_only():
    """``independent_rig.py --ideal`` measures what one difference of form costs: each ideal
    sets its own fields and leaves every other field of the unit as drawn."""
    unit = iu.spread_unit(np.random.default_rng(3))
    fields = set(iu.asdict(unit))
    for name, change in iu.IDEALS.items():
        made = iu.ideal(unit, [name])
        differ = {f for f in fields if getattr(made, f) != getattr(unit, f)}
        assert differ == set(change(unit)), (name, differ)
    assert iu.ideal(unit, []) == unit
    both = iu.ideal(unit, ["cogging", "hall"])
    assert (both.cogging, both.hall_error_deg) == (0.0, 0.0)


def test_the_fig10_parts_take_each_fault_out_once_and_alone_once():
    """``--set fig10-parts``: the set, the set less each of its four faults, and each fault
    alone at its Fig. 10 magnitude (severities compared as the benchmark's verdicts read
    them)."""
    import independent_rig as ir

    full = ir.severities(ir.FIG10)
    assert all(v > 0 for v in full.values())
    parts = {name: ir.severities(f) for name, f in ir.FIG10_PARTS.items()}
    assert parts["fig10.csv"] == full
    for fault in full:
        key = "short" if fault == "short_circuit" else fault
        assert parts[f"fig10-no-{key}.csv"] == {**full, fault: 0.0}
        alone = {f: (v if f == fault else 0.0) for f, v in full.items()}
        assert parts[f"{key}-alone.csv"] == alone
    assert len(parts) == 9
