"""Commissioning a unit: a perturbed actuator's parameters recovered from a healthy recording,
a loadable unit set with provenance, and refusals of recordings that cannot commission."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from emaprog.cli import app
from emaprog.config import parameters
from emaprog.config.parameters import ParameterFile, derive
from emaprog.config.scenario import ConstantLoad, load_scenario
from emaprog.io.storage import write_trace
from emaprog.models import reference

from .conftest import CONFIGS

#: A unit off the shipped set by ordinary build tolerances (docs/reference.md, Campaign YAML), and its hinge moment.
UNIT = {
    "motor_inertia": 1.08,
    "surface_inertia": 0.92,
    "motor_viscous": 1.25,
    "static_friction": 1.10,
    "dynamic_friction": 1.05,
    "phase_resistance": 1.10,
    "back_emf_constant": 0.98,
    "phase_inductance": 0.95,
    "transmission_stiffness": 0.85,
}
HINGE = 60.0  # [N m]
ELECTRICAL = ("phase_resistance", "back_emf_constant", "phase_inductance")


@functools.cache
def unit_parameters():
    spec = parameters.load("default").spec.model_dump()
    for name, factor in UNIT.items():
        spec["electrical" if name in ELECTRICAL else "mechanical"][name] *= factor
    return derive(ParameterFile.model_validate(spec), "perturbed unit")


def healthy_recording(path, noise: bool = False, **update):
    scenario = load_scenario(CONFIGS / "chirp-nominal.yaml").model_copy(
        update={"load": ConstantLoad(kind="constant", torque=HINGE), **update}
    )
    return write_trace(path, reference.simulate(scenario, unit_parameters(), with_noise=noise))


def rigid_inertia(values: dict) -> float:
    """Motor plus reflected surface inertia [kg m^2]: what a rigid actuator shows."""
    return values["motor_inertia"] + values["surface_inertia"] / 180.0**2


def unit_error(unit) -> dict[str, float]:
    """|commissioned / true - 1| per parameter, and the rigid inertia's (``rigid``)."""
    values = {**unit.spec.mechanical.model_dump(), **unit.spec.electrical.model_dump()}
    true = unit_parameters().spec
    truth = {**true.mechanical.model_dump(), **true.electrical.model_dump()}
    errors = {name: abs(values[name] / truth[name] - 1.0) for name in UNIT}
    errors["rigid"] = abs(rigid_inertia(values) / rigid_inertia(truth) - 1.0)
    return errors


def assert_recovered(errors: dict[str, float], inertia: float, stiffness: float = 0.06) -> None:
    """The accuracy of test_commissioning_recovers_a_perturbed_unit (its docstring), each
    inertia within ``inertia`` and the transmission stiffness within ``stiffness``."""
    assert errors["back_emf_constant"] < 0.015 and errors["rigid"] < 0.015
    assert errors["motor_viscous"] < 0.08 and errors["dynamic_friction"] < 0.05
    assert errors["transmission_stiffness"] < stiffness
    assert errors["motor_inertia"] < inertia and errors["surface_inertia"] < inertia


def test_commissioning_recovers_a_perturbed_unit(tmp_path):
    """Noise-free recording of the unit (chirp, 60 N m hinge moment), fitted from `default`.

    Tolerances (what the Monitor can resolve against the three-phase Reference, whose
    0.4 % nominal mismatch the fit partly absorbs): back-EMF constant 1.5 %, rigid inertia
    1.5 % (measured under 1 % on the Intel machines this was written on, 1.23 % and 1.32 %
    on an AMD znver3: the last-ulp differences of its libm move the fit's end point along
    the weakly determined resistance-inductance direction, which the commissioning reports
    as determined to 3 % only; k_e's own standard error is 3 %), viscous friction 8 %
    (measured -6.3 % there, its standard error 11 %), dynamic friction 5 %, stiffness 6 % (the compliant mode is seen
    through the 25 us Monitor step), each inertia 5 % (they separate only through that
    mode), hinge moment 2 N m. Resistance and inductance barely change a current-regulated
    drive's response: they must be reported as not determined or fitted within 5 %, never
    fitted wrongly (measured: resistance held, inductance fitted within 0.01 %; on the AMD
    machine both fitted, within 1.6 % and 1.0 %).
    """
    recording = healthy_recording(tmp_path / "healthy.parquet")
    out = tmp_path / "units" / "ema-7.yaml"
    result = CliRunner().invoke(app, ["commission", str(recording), "-o", str(out)])
    assert result.exit_code == 0, result.output
    unit = parameters.load(str(out))
    fitted = unit.spec.commissioning.fitted
    values = {**unit.spec.mechanical.model_dump(), **unit.spec.electrical.model_dump()}

    errors = unit_error(unit)
    assert_recovered(errors, inertia=0.05)
    assert abs(unit.spec.commissioning.recordings[0].hinge_moment - HINGE) < 2.0
    held = set(unit.spec.commissioning.not_determined)
    for name in ("phase_resistance", "phase_inductance"):  # held, or if fitted then right
        assert name in held or errors[name] < 0.05, (name, errors[name])
    base = parameters.load("default").spec
    for name in held:  # held: the base value (static friction: the base static/dynamic ratio)
        assert name not in fitted
        if name == "static_friction":
            assert values[name] / values["dynamic_friction"] == pytest.approx(
                base.mechanical.static_friction / base.mechanical.dynamic_friction, rel=1e-12
            )
        else:
            assert (
                values[name]
                == base.model_dump()["electrical" if name in ELECTRICAL else "mechanical"][name]
            )
    assert set(fitted) | held == set(UNIT)
    assert all(f.standard_error > 0 for f in fitted.values())
    assert len(unit.spec.commissioning.recordings[0].sha256) == 64
    assert "commissioned on" in unit.spec.changes[-1]
    # the unit set is usable wherever a set is: the Monitor simulates with it
    result = CliRunner().invoke(
        app,
        [
            "simulate",
            str(CONFIGS / "chirp-nominal.yaml"),
            "--model",
            "monitor",
            "-p",
            str(out),
            "-o",
            str(tmp_path / "m.parquet"),
        ],
    )
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize(
    "case,fragment",
    [
        ("at rest", "barely moves"),
        ("too short", "at least 0.2 s"),
        ("not this actuator", "still misses"),
    ],
)
def test_recordings_that_cannot_commission_exit_2_and_write_nothing(tmp_path, case, fragment):
    if case == "at rest":
        from emaprog.config.scenario import ConstantCommand

        path = healthy_recording(
            tmp_path / "rest.parquet", command=ConstantCommand(kind="constant", offset=0.0)
        )
    elif case == "too short":
        path = healthy_recording(tmp_path / "short.parquet", duration=0.1)
    else:  # a current channel twice too large: no plausible unit explains it
        import pyarrow.parquet as pq

        path = healthy_recording(tmp_path / "scaled.parquet")
        table = pq.read_table(path)
        current = table.column("current").to_numpy() * 2.0
        import pyarrow as pa

        table = table.set_column(
            table.column_names.index("current"), table.schema.field("current"), pa.array(current)
        )
        pq.write_table(table, path)
    out = tmp_path / "unit.yaml"
    result = CliRunner().invoke(app, ["commission", str(path), "-o", str(out)])
    assert result.exit_code == 2, result.output
    assert fragment in result.output and path.name in result.output
    assert "Traceback" not in result.output and not out.exists()


@pytest.mark.slow
def test_identification_against_the_unit_can_use_its_commissioning_recording(tmp_path):
    """`identify.nominal_correction: recording` with a commissioned set subtracts the
    commissioning recording's own residual when the inspection repeats its command on its
    grid, and says so; with the recording gone it falls back to `reference` and says why.
    The faulty inspection (a 20 % short on B) is identified within tolerance either way."""
    import json
    import shutil

    import yaml

    healthy = healthy_recording(tmp_path / "healthy.parquet", noise=True)
    unit = tmp_path / "unit.yaml"
    assert CliRunner().invoke(app, ["commission", str(healthy), "-o", str(unit)]).exit_code == 0
    faults = load_scenario(CONFIGS / "short-circuit.yaml").faults
    inspection = healthy_recording(
        tmp_path / "inspection.parquet", noise=True, faults=faults, seed=99
    )
    settings = load_scenario(CONFIGS / "chirp-nominal.yaml").model_dump(mode="json")
    settings["identify"].update(nominal_correction="recording", nuisances=["hinge_moment"])
    scenario = tmp_path / "inspection.yaml"
    scenario.write_text(yaml.safe_dump(settings))

    def identify(folder: str) -> dict:
        result = CliRunner().invoke(
            app,
            [
                "identify",
                str(inspection),
                "--scenario",
                str(scenario),
                "--parameters",
                str(unit),
                "-o",
                str(tmp_path / folder),
            ],
        )
        assert result.exit_code == 0, result.output
        return json.loads((tmp_path / folder / "report.json").read_text())

    report = identify("with-recording")
    assert report["correction"]["applied"] == "recording"
    assert "healthy.parquet" in report["correction"]["note"]
    true_fraction = faults.short_circuit.b
    assert abs(report["estimate"]["short_circuit"]["b"] - true_fraction) < 0.03
    shutil.move(healthy, tmp_path / "moved.parquet")
    report = identify("without")
    assert report["correction"]["applied"] == "reference"
    assert "not found" in report["correction"]["note"]
    assert abs(report["estimate"]["short_circuit"]["b"] - true_fraction) < 0.03


@pytest.mark.parametrize(
    "missed,shown", [(0.1004, "10.04 %"), (0.10000004, "10.000004 %"), (0.137, "14 %")]
)
def test_a_refusal_never_prints_the_residual_as_its_limit(missed, shown):
    """The issue's refusal read "misses 10 % of the current's RMS (at most 10 %)": the residual
    rounded to the limit it broke. It gets the digits that tell it from the limit, no more."""
    from types import SimpleNamespace

    from emaprog.errors import InputError
    from emaprog.fitting.commission import MAX_CURRENT_RESIDUAL, check_explained

    fit = SimpleNamespace(residuals=[{"current": missed, "position": 0.0, "speed": 0.0}])
    with pytest.raises(InputError) as refused:
        check_explained(fit, [SimpleNamespace(source="rig/healthy-1.csv")])
    message = refused.value.message.replace("%", " %")
    assert f"misses {shown} of the current's RMS" in message
    assert f"(at most {MAX_CURRENT_RESIDUAL:.0%})".replace("%", " %") in message


#: Build tolerances of the unit-to-unit parameters (+-, relative): robustness.yaml's spread.
TOLERANCES = {
    "motor_inertia": 0.10,
    "surface_inertia": 0.10,
    "motor_viscous": 0.30,
    "dynamic_friction": 0.15,
    "static_friction": 0.15,
    "phase_resistance": 0.10,
    "back_emf_constant": 0.03,
    "phase_inductance": 0.10,
    "transmission_stiffness": 0.20,
}


def test_build_tolerances_are_commissionings_prior(tmp_path):
    """A base set with ``tolerances`` commissions by maximum a posteriori: nothing is held,
    every parameter is fitted with a standard error no larger than its prior's (information
    only adds: exact up to rounding), and the one the recording barely determines (the
    winding resistance of a current-regulated drive, held at the base without tolerances)
    is fitted within its tolerance with a standard error of at least half the prior's.

    The unit (off the base by UNIT, resistance at +10 %: the tolerance's edge) from the
    same noise-free recording as ``test_commissioning_recovers_a_perturbed_unit``, with
    its tolerances: k_e 1.5 %, rigid inertia 1.5 %, viscous 8 %, dynamic friction 5 %,
    hinge moment 2 N m; the split of the rigid inertia between motor and surface and the
    stiffness, which only the compliant mode shows and the prior pulls toward the base's,
    within their build tolerance, 10 % (measured 1.5 / 4.2 / under 6 % on one CPU, 5.5 / 8.4 /
    7.5 % on another: the fit's path there moves with the last digits of the arithmetic,
    while the rigid inertia stays within 0.7 %); resistance 6 % (measured -3.8 %, -9.1 % when
    held)."""
    import math

    import yaml

    base = parameters.load("default")
    spec = base.spec.model_dump(mode="json", exclude_none=True)
    spec["tolerances"] = TOLERANCES
    base_file = tmp_path / "with-tolerances.yaml"
    base_file.write_text(yaml.safe_dump(spec, sort_keys=False))
    recording = healthy_recording(tmp_path / "healthy.parquet")
    out = tmp_path / "unit.yaml"
    result = CliRunner().invoke(
        app, ["commission", str(recording), "-p", str(base_file), "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    unit = parameters.load(str(out))
    record = unit.spec.commissioning
    assert record.not_determined == []
    assert record.tolerances == TOLERANCES
    assert set(record.fitted) == set(TOLERANCES)
    errors = unit_error(unit)
    assert_recovered(errors, inertia=0.10, stiffness=0.10)
    assert errors["phase_resistance"] < 0.06
    assert abs(record.recordings[0].hinge_moment - HINGE) < 2.0
    # the linearised (posterior) errors against the prior's width, from the fit itself
    from emaprog.fitting import commission
    from emaprog.io.storage import read_trace

    with_tolerances = parameters.load(str(base_file))
    fit = commission.fit(
        [commission.prepare(read_trace(recording), str(recording), with_tolerances)],
        with_tolerances,
    )
    for name, error in fit.standard_errors.items():
        width = TOLERANCES[name] / math.sqrt(3.0)
        if name != "static_friction":  # static = dynamic x ratio: both errors add
            assert error / fit.values[name] <= width * (1.0 + 1e-9), name
    resistance = fit.standard_errors["phase_resistance"] / fit.values["phase_resistance"]
    assert resistance >= 0.5 * TOLERANCES["phase_resistance"] / math.sqrt(3.0)
    factor = fit.values["phase_resistance"] / fit.base["phase_resistance"]
    assert abs(factor - 1.0) <= TOLERANCES["phase_resistance"]


@pytest.mark.parametrize(
    "tolerances, fragment",
    [
        ({"gear_ratio": 0.1}, "no tolerance for gear_ratio"),
        ({"motor_inertia": 1.5}, "tolerances.motor_inertia"),
    ],
)
def test_a_tolerance_commissioning_cannot_use_exits_2(tmp_path, tolerances, fragment):
    """A tolerance on a parameter commissioning does not fit, or past +-100 %: exit 2, one
    message naming the file and the key."""
    import yaml

    spec = parameters.load("default").spec.model_dump(mode="json", exclude_none=True)
    spec["tolerances"] = tolerances
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    result = CliRunner().invoke(app, ["check", str(path)])
    assert result.exit_code == 2
    assert fragment in result.output and str(path) in result.output
    assert "Traceback" not in result.output


def test_posterior_variances_survive_a_wide_information_scale():
    """The posterior's inverse under tolerances: the recordings' information spans 12
    orders (calibration-pwm case 155: 3e12 for the back-EMF constant, 0 for static
    friction) against the prior's 0.7. The inverse is the closed form of its 2 x 2 coupled
    block and the diagonal's reciprocal (relative 1e-9: rounding), a column that changes
    nothing and has no prior stays infinite; the unscaled inverse read every direction as
    blind but the strongest (its floor is 1e-12 of the largest eigenvalue), which kept a
    fitted spring out."""
    from emaprog.fitting.commission import _scaled_inverse
    from emaprog.identification.confidence import information_inverse

    a, b, c = 3.2e12 + 0.7, 0.7 + 4.0, 0.9 * math.sqrt(3.2e12 * 4.0)  # correlated 0.9
    posterior = np.zeros((4, 4))
    posterior[:2, :2] = [[a, c], [c, b]]
    posterior[2, 2] = 0.7  # the prior alone (static friction never sticks)
    cov = _scaled_inverse(posterior)
    determinant = a * b - c * c
    expected = np.array([[b, -c], [-c, a]]) / determinant
    assert np.allclose(cov[:2, :2], expected, rtol=1e-9, atol=0.0)
    assert cov[2, 2] == pytest.approx(1.0 / 0.7, rel=1e-12)
    assert np.isinf(cov[3, 3])  # the fourth column: no information, no prior
    assert np.isinf(np.diag(information_inverse(posterior))[1:3]).all()
