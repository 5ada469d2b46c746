"""Shared fixtures: the shipped parameter set, scenarios, and cached Reference runs."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

from emaprog.config import parameters
from emaprog.config.scenario import load_scenario
from emaprog.faults import HEALTHY, MonitorFaults, flatten, monitor_form, reference_form
from emaprog.kernels.monitor import moving_average
from emaprog.models import monitor, reference
from emaprog.models.common import inputs

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"


@pytest.fixture(scope="session")
def params():
    return parameters.load("default")


@functools.cache
def scenario(name: str):
    return load_scenario(CONFIGS / f"{name}.yaml")


@functools.cache
def reference_run(name: str, faults=None, noise: bool = False):
    """Reference columns and energy ledger of a shipped scenario (cached per session)."""
    sc = scenario(name)
    p = parameters.load("default")
    f = reference_form(flatten(sc.faults)) if faults is None else faults
    return reference.run(p, inputs(sc, p), f, sc.seed, with_noise=noise)


@functools.cache
def monitor_run(name: str, faults=None):
    sc = scenario(name)
    p = parameters.load("default")
    f = (
        monitor_form(flatten(sc.faults), p.spec.monitor.eccentricity_gain)
        if faults is None
        else faults
    )
    return monitor.run(p, inputs(sc, p), f)


def low_pass(x: np.ndarray, width: int = 10) -> np.ndarray:
    out = np.empty_like(x)
    moving_average(np.ascontiguousarray(x), width, out)
    return out


def nrmse(model: np.ndarray, truth: np.ndarray, skip: int = 100) -> float:
    """RMS error over RMS of the truth, start-up samples left out [-]."""
    m, t = model[skip:], truth[skip:]
    return float(np.sqrt(np.mean((m - t) ** 2)) / np.sqrt(np.mean(t**2)))


#: The healthy Monitor (Z = 0).
MONITOR_HEALTHY = MonitorFaults(*HEALTHY)

__all__ = [
    "CONFIGS",
    "HEALTHY",
    "MONITOR_HEALTHY",
    "ROOT",
    "low_pass",
    "monitor_run",
    "nrmse",
    "reference_run",
    "scenario",
]
