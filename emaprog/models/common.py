"""What the Reference and Monitor runners share: inputs on the grid and provenance."""

from __future__ import annotations

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


def inputs_from_trace(trace, load_spec=None) -> Inputs:
    """Inputs of a measured trace: its command, and the scenario's load where known."""
    t = np.ascontiguousarray(trace.time)
    if load_spec is None:
        return Inputs(t, np.ascontiguousarray(trace["command"]), np.zeros(t.size), 0.0)
    torque, stiffness = signals.load(load_spec, t)
    return Inputs(t, np.ascontiguousarray(trace["command"]), torque, stiffness)


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
