"""What the Reference and Monitor runners share: inputs on the grid and provenance."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .. import __version__, signals
from ..kernels.structs import Drive
from ..config.parameters import Parameters
from ..config.scenario import Scenario


class Inputs(NamedTuple):
    """Operating inputs sampled on the controller grid."""

    time: np.ndarray  # [s]
    command: np.ndarray  # [rad]
    load_torque: np.ndarray  # [N m]
    load_stiffness: float  # [N m/rad]

    def drive(self, hinge_moment: float = 0.0) -> Drive:
        """The kernels' :class:`~emaprog.kernels.structs.Drive`, plus a constant hinge moment [N m]."""
        return Drive(self.command, self.load_torque, float(self.load_stiffness), float(hinge_moment))


def inputs(scenario: Scenario, params: Parameters) -> Inputs:
    t = signals.time_grid(scenario.duration, params.spec.controller.rate)
    cmd = signals.command(scenario.command, t, scenario.duration)
    torque, stiffness = signals.load(scenario.load, t)
    return Inputs(t, cmd, torque, stiffness)


def inputs_from_trace(trace, rate: float, load_spec=None) -> Inputs:
    """Inputs on the controller grid (``rate`` [Hz]) for a measured trace at any rate.

    The trace's first sample is time 0 (the Monitor starts at rest there). When the
    trace is already on the controller grid its command is used as it is; otherwise
    the command is interpolated linearly onto the grid, which covers the last
    recorded instant. The load is the scenario's where known, else none.
    """
    t_rec = np.asarray(trace.time, dtype=np.float64) - float(trace.time[0])
    n = int(math.ceil(t_rec[-1] * rate - 1e-9)) + 1
    grid = np.arange(n, dtype=np.float64) / rate
    command = np.asarray(trace["command"], dtype=np.float64)
    if grid.size == t_rec.size and np.allclose(grid, t_rec, rtol=0.0, atol=1e-9 / rate):
        grid, command = t_rec, np.ascontiguousarray(command)
    else:
        command = np.interp(grid, t_rec, command)
    if load_spec is None:
        return Inputs(grid, command, np.zeros(grid.size), 0.0)
    torque, stiffness = signals.load(load_spec, grid)
    return Inputs(grid, command, torque, stiffness)


class Instants(NamedTuple):
    """Where recorded samples fall on the controller grid: ``t = (index + fraction) / rate``."""

    index: np.ndarray  # (n_rec,) int64, grid sample at or before each recorded instant
    fraction: np.ndarray  # (n_rec,) float64 in [0, 1): the way to the next grid sample

    def sample(self, x: np.ndarray) -> np.ndarray:
        """A controller-grid signal at the recorded instants (linear interpolation)."""
        nxt = np.minimum(self.index + 1, x.size - 1)
        return np.where(self.fraction == 0.0, x[self.index],
                        x[self.index] + self.fraction * (x[nxt] - x[self.index]))


def recorded_instants(trace_time: np.ndarray, grid: np.ndarray, shift: float = 0.0) -> Instants:
    """The :class:`Instants` of a trace's samples, moved by ``shift`` [s], on a controller grid
    starting at 0."""
    t_rec = np.asarray(trace_time, dtype=np.float64) - float(trace_time[0]) + shift
    if grid.size == t_rec.size and np.array_equal(grid, t_rec):
        return Instants(np.arange(grid.size, dtype=np.int64), np.zeros(grid.size))
    period = grid[1] - grid[0]
    # instants outside the grid (a shift at either end) read its first or last sample
    position = np.clip(t_rec / period, 0.0, grid.size - 1.0)
    index = np.minimum(np.floor(position + 1e-9).astype(np.int64), grid.size - 1)
    fraction = np.clip(position - index, 0.0, 1.0)
    fraction[(np.abs(fraction) < 1e-9) | (index == grid.size - 1)] = 0.0
    return Instants(index, fraction)


def provenance(model: str, scenario: Scenario, params: Parameters, **extra) -> dict:
    """The ``emaprog`` metadata of a trace (SPEC 4)."""
    return {
        "emaprog_version": __version__,
        "model": model,
        "scenario": scenario.model_dump(mode="json"),
        "parameters": params.values(),
        "parameter_file": params.source_file,
        "seed": scenario.seed,
        "sample_rate": params.spec.controller.rate,
        **extra,
    }
