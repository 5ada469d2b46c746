"""Twin experiments: inject faults in the noisy Reference Model, recover them with the GA.

Tolerances are docs/reference.md's (Faults) (friction 5 % relative, backlash 5e-5 rad, shorted
fraction 0.03 on the right phase, zeta 0.05), on every shipped config: the
Monitor's commutation transients, the single-phase start and the polish in the
eccentricity plane (emaprog.identification.run) brought the last two gaps in.
"""

from __future__ import annotations

import functools
import json
import math

import pytest
from typer.testing import CliRunner

from emaprog import api
from emaprog.cli import app

from .conftest import CONFIGS

pytestmark = pytest.mark.slow


@functools.cache
def twin(name: str, tmp: str) -> dict:
    from pathlib import Path

    trace = Path(tmp) / f"{name}.parquet"
    api.simulate(CONFIGS / f"{name}.yaml", output=trace)
    return api.identify(trace, output=Path(tmp) / f"{name}-report").data


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return str(tmp_path_factory.mktemp("twins"))


def test_healthy_trace_is_all_nominal(workdir):
    report = twin("chirp-nominal", workdir)
    assert set(report["health"].values()) == {"nominal"}
    assert abs(report["error"]["friction"]) < 0.05


def test_friction_recovered(workdir):
    report = twin("friction", workdir)
    assert abs(report["error"]["friction"]) / report["truth"]["friction"] < 0.05
    assert (
        report["health"]["short_circuit"] == "nominal" and report["health"]["backlash"] == "nominal"
    )


def test_backlash_recovered(workdir):
    report = twin("backlash", workdir)
    assert abs(report["error"]["backlash"]) < 5e-5
    assert report["health"]["backlash"] != "nominal" and report["health"]["friction"] == "nominal"


def test_short_circuit_recovered_on_the_right_phase(workdir):
    report = twin("short-circuit", workdir)
    assert report["short_circuit_phase"] == "b"
    for phase in "abc":
        assert abs(report["error"]["short_circuit"][phase]) < 0.03
    assert report["estimate"]["eccentricity"]["zeta"] < 0.05
    assert report["health"]["eccentricity"] == "nominal"


def test_eccentricity_detected(workdir):
    report = twin("eccentricity", workdir)
    assert report["health"]["eccentricity"] != "nominal"
    assert abs(report["error"]["eccentricity"]["zeta"]) < 0.05
    assert abs(report["error"]["eccentricity"]["phase"]) < 0.2  # [rad] measured 0.01
    assert report["health"]["short_circuit"] == "nominal"


def test_fig10_combination(workdir):
    report = twin("fig10-multiple-faults", workdir)
    err = report["error"]
    assert abs(err["friction"]) / 1.8 < 0.05
    assert abs(err["backlash"]) < 5e-5
    assert abs(err["eccentricity"]["zeta"]) < 0.05
    assert report["short_circuit_phase"] == "a"
    for phase in "abc":
        assert abs(err["short_circuit"][phase]) < 0.03
    assert set(report["health"].values()) <= {"incipient", "degraded"}


TWINS = (
    "chirp-nominal",
    "friction",
    "backlash",
    "short-circuit",
    "eccentricity",
    "fig10-multiple-faults",
)


def test_intervals_hold_the_twins_truth(workdir):
    """Over the six shipped twins (42 quantity estimates, 36 with a defined truth for the
    phase) the 90 % intervals hold the truth in at least 80 % (at a true 90 %, fewer than
    80 % of about 40 happens with 3 % probability), every interval holds its estimate, and
    none is wider than twice the tolerance (measured: about a quarter of it)."""
    from emaprog.faults import QUANTITIES, flat_from_nested

    covered, total = 0, 0
    for name in TWINS:
        report = twin(name, workdir)
        estimate = flat_from_nested(report["estimate"])
        truth = flat_from_nested(report["truth"])
        for fault, value in report["interval"].items():
            items = value.items() if isinstance(value, dict) else [(None, value)]
            for key, (low, high) in items:
                q = next(
                    q
                    for q in QUANTITIES.values()
                    if q.name == fault or (q.key == key and q.name.startswith(fault))
                )
                if q.circular:
                    if truth["eccentricity_zeta"] < 0.08:
                        continue  # the angle of an absent eccentricity is not defined
                    half, centre = (high - low) / 2, (high + low) / 2
                    inside = abs(math.remainder(truth[q.name] - centre, 2 * math.pi)) <= half
                else:
                    assert low <= estimate[q.name] <= high
                    inside = low <= truth[q.name] <= high
                    width = (high - low) / (truth[q.name] if q.measure == "relative" else 1.0)
                    assert width <= 2 * q.tolerance, (name, q.name, low, high)
                covered += inside
                total += 1
    assert covered >= 0.8 * total, (covered, total)


def test_cli_demo_writes_the_report_and_is_reproducible(tmp_path):
    runner = CliRunner()
    trace = tmp_path / "t.parquet"
    assert (
        runner.invoke(
            app, ["simulate", str(CONFIGS / "backlash.yaml"), "-o", str(trace), "--plot"]
        ).exit_code
        == 0
    )
    assert trace.with_suffix(".png").stat().st_size > 10_000
    outputs = []
    for run in ("one", "two"):
        result = runner.invoke(app, ["identify", str(trace), "-o", str(tmp_path / run)])
        assert result.exit_code == 0, result.output
        assert "health:" in result.output and "backlash" in result.output
        report = json.loads((tmp_path / run / "report.json").read_text())
        for key in (
            "estimate",
            "truth",
            "error",
            "health",
            "fitness",
            "evaluations",
            "elapsed_s",
            "seed",
            "settings",
            "emaprog_version",
        ):
            assert key in report
        # the libraries and CPU the numbers came from (docs/reference.md, Identification report)
        assert {"numpy", "scipy", "numba", "python", "machine", "cpu"} <= set(report["environment"])
        assert all(isinstance(v, str) and v for v in report["environment"].values())
        for figure in ("fit.png", "convergence.png", "report.md"):
            assert (tmp_path / run / figure).stat().st_size > 1000
        report.pop("elapsed_s")
        report.pop("trace")
        outputs.append(report)
    assert outputs[0] == outputs[1]  # same seed, same numbers


def test_unknown_hinge_moment_is_estimated_as_a_nuisance(tmp_path):
    """Fig. 10 under a 60 N m hinge moment the scenario does not mention, nuisances on:
    the hinge moment is estimated beside the faults (within 2 N m; measured 0.1-0.4 on the
    regression cases), reported under `nuisance` with no verdict and a 90 % interval that
    holds the truth (measured [57.6, 62.6] N m; no wider than 10 N m: the calibrated law
    gave a median width of 4.6 N m on the robustness units), and every fault within
    tolerance. Without the nuisance the same recording reads friction 0.6 off (the regression
    cases: 0 of 10 within tolerance)."""

    from emaprog.config.scenario import ConstantLoad, load_scenario

    scenario = load_scenario(CONFIGS / "fig10-multiple-faults.yaml")
    loaded = scenario.model_copy(update={"load": ConstantLoad(kind="constant", torque=60.0)})
    frame = api.simulate(loaded)
    frame.attrs["emaprog"]["scenario"]["load"] = {"kind": "none"}  # the user does not know it
    frame.attrs["emaprog"]["scenario"]["identify"]["nuisances"] = [
        "hinge_moment",
        "resistance_factor",
    ]
    report = api.identify(frame)
    assert abs(report.data["nuisance"]["hinge_moment"] - 60.0) < 2.0
    low, high = report.data["nuisance_interval"]["hinge_moment"]
    assert low <= 60.0 <= high and high - low <= 10.0, (low, high)
    assert "hinge_moment" not in report.health and "resistance_factor" not in report.health
    err = report.error
    assert abs(err["friction"]) / 1.8 < 0.05 and abs(err["backlash"]) < 5e-5
    assert abs(err["eccentricity"]["zeta"]) < 0.05 and report.data["short_circuit_phase"] == "a"
    assert all(abs(err["short_circuit"][x]) < 0.03 for x in "abc")
