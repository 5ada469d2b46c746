"""Monitor Model runner: same interface as the Reference runner, deterministic."""

from __future__ import annotations

import numpy as np

from ..faults import FaultParams, to_params
from ..kernels.monitor import (
    ECCENTRICITY_PAIR, ECCENTRICITY_PAPER, SHORT_CIRCUIT_AVERAGED, SHORT_CIRCUIT_MODULATED,
    simulate_monitor,
)
from ..numerics import DEFAULT, Numerics
from ..parameters import Parameters
from ..scenario import Scenario
from ..storage import Trace
from .common import Inputs, inputs, provenance

SHORT_CIRCUIT_MODELS = {"modulated": SHORT_CIRCUIT_MODULATED, "averaged": SHORT_CIRCUIT_AVERAGED}
ECCENTRICITY_MODELS = {"pair": ECCENTRICITY_PAIR, "paper": ECCENTRICITY_PAPER}


def model_flags(params: Parameters) -> tuple[int, int, float, float, bool]:
    """Kernel arguments of the parameter set's monitor section.

    (PSC law, RE law, torque gain scale [-], commutation loss [s/rad],
    commutation transients modelled).
    """
    m = params.spec.monitor
    return (SHORT_CIRCUIT_MODELS[m.short_circuit_model], ECCENTRICITY_MODELS[m.eccentricity_model],
            m.torque_gain_scale, m.commutation_loss, m.commutation_model == "transient")


def run(params: Parameters, inp: Inputs, faults: FaultParams, numerics: Numerics = DEFAULT,
        flags: tuple[int, int, float, float, bool] | None = None) -> dict[str, np.ndarray]:
    """Run the Monitor kernel; ``faults.ecc_magnitude`` is Z. Returns trace columns."""
    n = inp.time.size
    names = ("position", "speed", "current", "motor_angle")
    out = {name: np.empty(n) for name in names}
    flags = flags if flags is not None else model_flags(params)
    simulate_monitor(inp.command, inp.load_torque, inp.load_stiffness, params.electrical,
                     params.mechanical, params.controller, params.sensors, faults, *flags,
                     numerics.monitor_substeps, *(out[name] for name in names))
    return {"time": inp.time, "command": inp.command, **out}


def simulate(scenario: Scenario, params: Parameters, numerics: Numerics = DEFAULT) -> Trace:
    """Simulate a scenario's true faults on the Monitor (zeta mapped through c)."""
    faults = to_params(scenario.faults, params.spec.monitor.eccentricity_gain)
    columns = run(params, inputs(scenario, params), faults, numerics)
    meta = provenance("monitor", scenario, params,
                      time_step=params.controller.period / numerics.monitor_substeps)
    return Trace(columns, meta)
