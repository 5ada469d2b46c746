"""The benchmark scripts: every one imports against today's package (a script that no longer
runs documents nothing), and the interval calibration's arithmetic on known distributions."""

from __future__ import annotations

import importlib
import math
import sys

import numpy as np
import pandas as pd
import pytest

from .conftest import ROOT

BENCHMARKS = ROOT / "benchmarks"


@pytest.fixture(scope="module", autouse=True)
def _on_path():
    sys.path.insert(0, str(BENCHMARKS))
    yield
    sys.path.remove(str(BENCHMARKS))


@pytest.mark.parametrize(
    "script", sorted(p.stem for p in BENCHMARKS.glob("*.py") if not p.stem.startswith("_"))
)
def test_every_benchmark_script_imports_and_has_a_main(script):
    module = importlib.import_module(script)
    assert callable(module.main)


def test_wilson_interval_closed_form():
    """45 of 50 at z = 1.645: centre (p + z^2/2n)/(1 + z^2/n) = 0.8795, half-width
    z sqrt(p(1-p)/n + z^2/4n^2)/(1 + z^2/n) = 0.0710 (worked by hand)."""
    from interval_factors import wilson

    low, high = wilson(45, 50)
    assert low == pytest.approx(0.8085, abs=5e-4) and high == pytest.approx(0.9505, abs=5e-4)


def test_calibration_recovers_the_law_the_errors_were_drawn_with():
    """Friction errors drawn normal with sd sqrt((2 sigma)^2 + (0.05 d)^2 + (0.001 L)^2), d
    = |k_f - 1|, L the fault load (a backlash estimate drawn apart makes it vary on its
    own; the three terms of comparable size), half the cases healthy: among candidate laws
    around it the calibration picks factor 2 (within 8 %: the grid's 5 % step and the
    sampling of a 90th percentile over 4000 draws; seeds 0-3 gave 2.0 or 1.9), share 0.05
    and load 0.001 exactly (their neighbours 0.0375 / 0.0625 and 0.0005 / 0.002 are
    candidates); an angle's factor likewise, with no load, and an angle whose true zeta is
    below the incipient threshold is not counted."""
    from interval_factors import Cases, fit

    from emaprog.faults import QUANTITIES, fault_load

    rng = np.random.default_rng(0)
    n = 4000
    sigma = rng.uniform(0.002, 0.01, n)
    true = np.where(np.arange(n) % 2 == 0, 1.0, rng.uniform(1.2, 3.0, n))
    incipient = {"friction": 0.15, "backlash": 1e-4, "short_circuit": 0.05, "eccentricity": 0.05}
    frame = pd.DataFrame({f"est_{q}": np.full(n, v.healthy) for q, v in QUANTITIES.items()})
    frame["est_backlash"] = rng.uniform(0.0, 1e-3, n)
    load = fault_load({**{q: frame[f"est_{q}"] for q in QUANTITIES}, "friction": true}, incipient)
    frame = frame.assign(
        true_friction=true,
        sigma_friction=sigma,
        est_friction=true
        + rng.normal(
            0.0,
            np.sqrt((2.0 * sigma) ** 2 + (0.05 * np.abs(true - 1.0)) ** 2 + (0.001 * load) ** 2),
        ),
        true_eccentricity_zeta=0.3,
        true_eccentricity_phase=6.2,
        est_eccentricity_phase=np.mod(6.2 + rng.normal(0.0, 2.0 * sigma), 2.0 * math.pi),
        sigma_eccentricity_phase=sigma,
    )
    factors = np.round(np.geomspace(1.0, 4.0, 29), 3)
    shares, loads = [0.0, 0.025, 0.0375, 0.05, 0.0625, 0.075], [0.0, 0.0005, 0.001, 0.002]
    factor, share, coefficient = fit(
        Cases(frame, "friction", incipient, twin=True), factors, shares, loads
    )
    assert factor == pytest.approx(2.0, rel=0.08) and share == 0.05 and coefficient == 0.001
    factor, share, coefficient = fit(
        Cases(frame, "eccentricity_phase", incipient, twin=True), factors, shares, loads
    )
    assert factor == pytest.approx(2.0, rel=0.08) and share == 0.0 and coefficient == 0.0
    frame["true_eccentricity_zeta"] = 0.01
    assert Cases(frame, "eccentricity_phase", incipient, twin=True).error.size == 0


def _results(directory, finished: int, planned: int, digest: str):
    """A sweep results directory with ``finished`` (empty) case rows of ``planned``."""
    import json

    (directory / "cases").mkdir(parents=True)
    for case in range(finished):
        (directory / "cases" / f"case-{case:06d}.parquet").touch()
    manifest = {"campaign": "c", "campaign_file": "campaigns/c.yaml", "planned": planned}
    (directory / "manifest.json").write_text(json.dumps({**manifest, "content_hash": digest * 32}))
    return directory


def test_written_unit_laws_give_the_spring_the_hinge_moments_factor_and_share(tmp_path):
    """The unit campaigns have no aerodynamic spring: writing the unit basis' hinge-moment law
    gives the spring's (basis unit) the same factor and share and no load term (its load is
    in another unit), the form's spring law is left alone, and each written basis names the
    campaign it comes from."""
    import json
    import shutil

    from interval_factors import LAWS_FILE, write_laws

    laws = tmp_path / "model_errors.json"
    shutil.copy(LAWS_FILE, laws)
    before = json.loads(laws.read_text())
    results = _results(tmp_path / "calunits", finished=4, planned=4, digest="ab")
    rows = [
        {"basis": "unit", "quantity": "hinge_moment", "proposed": (5.5, 0.01, 0.02)},
        {"basis": "unit", "quantity": "friction", "proposed": (1.5, 0.02, 0.001), "ratio_ref": 9.0},
    ]
    after = json.loads(write_laws(rows, [results], laws).read_text())
    assert after["laws"]["nuisance"]["hinge_moment"] == [5.5, 0.01, 0.02]
    assert after["laws"]["nuisance"]["hinge_stiffness"] == [5.5, 0.01, 0.0]
    assert after["laws"]["form"]["hinge_stiffness"] == before["laws"]["form"]["hinge_stiffness"]
    assert after["laws"]["unit"]["friction"] == [1.5, 0.02, 0.001]
    assert after["mismatch_ratio"]["unit"] == 9.0
    assert "campaigns/c.yaml (4 cases, hash abababababab)" in after["provenance"]["unit"]
    assert after["explained_limit"] == before["explained_limit"]  # the unit basis has none


def test_written_form_laws_take_the_worst_calibration_fit_as_the_explained_limit(tmp_path):
    """On the form basis the ratio up to which the Monitor explains a recording is the worst
    fit among the calibration units, rounded up to three digits so that it stays in (43.61
    -> 43.7), beside the 95th percentile the laws are calibrated under; a calibration
    stopped early names how many of its cases it holds."""
    import json
    import shutil

    from interval_factors import LAWS_FILE, write_laws

    laws = tmp_path / "model_errors.json"
    shutil.copy(LAWS_FILE, laws)
    results = _results(tmp_path / "cal", finished=3, planned=8, digest="cd")
    row = {"basis": "form", "quantity": "friction", "proposed": (4.0, 0.03, 0.001)}
    after = json.loads(
        write_laws([{**row, "ratio_ref": 26.31, "limit_ref": 43.61}], [results], laws).read_text()
    )
    assert after["explained_limit"]["form"] == 43.7
    assert after["mismatch_ratio"]["form"] == 26.31
    assert (
        "campaigns/c.yaml (the first 3 of its 8 cases, hash cdcdcdcdcdcd)"
        in (after["provenance"]["form"])
    )


def test_commission_floor_recovers_the_model_error_the_errors_were_drawn_with():
    """Errors drawn as N(0, se^2 + floor^2) with a known floor of 3 % over 4000 units: the
    calibrated floor is within 0.4 points of it (the 90 % coverage quantile's sampling error
    on 4000 draws is about 0.2 points) and its coverage is 90 % to 1 point."""
    import numpy as np
    import pandas as pd

    commission_errors = importlib.import_module("commission_errors")
    rng = np.random.default_rng(5)
    se = rng.uniform(0.002, 0.01, 4000)
    err = rng.normal(0.0, np.hypot(se, 0.03))
    frame = pd.DataFrame(
        {"commission_err_back_emf_constant": err, "commission_se_back_emf_constant": se}
    )
    for name in commission_errors.PARAMETERS:
        for column in (f"commission_err_{name}", f"commission_se_{name}"):
            if column not in frame:
                frame[column] = np.nan
    found = commission_errors.calibrate(frame)["back_emf_constant"]
    assert abs(found["floor"] - 0.03) < 0.004 and abs(found["coverage"] - 0.90) < 0.01
    assert found["coverage_linearised"] < 0.5
