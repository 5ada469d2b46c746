"""The benchmark scripts: every one imports against today's package (a script that no longer
runs documents nothing), and the interval calibration's arithmetic on known distributions."""

from __future__ import annotations

import importlib
import math
import sys
from pathlib import Path

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


@pytest.mark.parametrize("script", sorted(p.stem for p in BENCHMARKS.glob("*.py")
                                          if not p.stem.startswith("_")))
def test_every_benchmark_script_imports_and_has_a_main(script):
    module = importlib.import_module(script)
    assert callable(module.main)


def test_wilson_interval_closed_form():
    """45 of 50 at z = 1.645: centre (p + z^2/2n)/(1 + z^2/n) = 0.8795, half-width
    z sqrt(p(1-p)/n + z^2/4n^2)/(1 + z^2/n) = 0.0710 (worked by hand)."""
    from interval_factors import wilson

    low, high = wilson(45, 50)
    assert low == pytest.approx(0.8085, abs=5e-4) and high == pytest.approx(0.9505, abs=5e-4)


def test_calibration_proposes_the_factor_that_covers_90_percent():
    """Errors drawn normal with twice the stated standard error: the proposed factor is
    twice today's within 5 % (the 90th percentile of |N(0,1)|/1.645 over 4000 draws has a
    sampling error near 2 %), for a linear quantity and for an angle on the circle."""
    from interval_factors import multipliers

    from emaprog.identification.confidence import Z90

    rng = np.random.default_rng(0)
    n = 4000
    se = rng.uniform(0.01, 0.05, n)
    frame = pd.DataFrame({
        "true_friction": np.full(n, 1.5), "se_friction": se,
        "est_friction": 1.5 + rng.normal(0.0, 2.0 * se),
        "true_eccentricity_zeta": np.full(n, 0.3), "est_eccentricity_zeta": np.full(n, 0.3),
        "se_eccentricity_zeta": np.full(n, 0.01),
        "true_eccentricity_phase": np.full(n, 6.2), "se_eccentricity_phase": se,
        "est_eccentricity_phase": np.mod(6.2 + rng.normal(0.0, 2.0 * se), 2.0 * math.pi),
    })
    incipient = {"eccentricity": 0.05}
    for name in ("friction", "eccentricity_phase"):
        need = multipliers(frame, name, incipient)
        assert need.size == n
        assert np.quantile(need, 0.9) == pytest.approx(2.0, rel=0.05)
    # an angle whose true zeta is below the incipient threshold is not counted
    frame["true_eccentricity_zeta"] = 0.01
    assert multipliers(frame, "eccentricity_phase", incipient).size == 0
    assert Z90 == pytest.approx(1.6448536, rel=1e-7)
