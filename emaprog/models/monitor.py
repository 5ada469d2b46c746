"""Monitor Model runner: same interface as the Reference runner, deterministic."""

from __future__ import annotations

import numpy as np

from ..config.parameters import Parameters
from ..config.scenario import Scenario
from ..faults import MonitorFaults, flatten, monitor_form
from ..io.storage import Trace
from ..kernels.monitor import (
    ECCENTRICITY_PAIR,
    ECCENTRICITY_PAPER,
    SHORT_CIRCUIT_AVERAGED,
    SHORT_CIRCUIT_MODULATED,
    simulate_monitor,
)
from ..kernels.structs import MonitorOptions, MonitorOutputs, Plant
from ..numerics import DEFAULT, Numerics
from .common import Inputs, inputs, provenance

SHORT_CIRCUIT_MODELS = {"modulated": SHORT_CIRCUIT_MODULATED, "averaged": SHORT_CIRCUIT_AVERAGED}
ECCENTRICITY_MODELS = {"pair": ECCENTRICITY_PAIR, "paper": ECCENTRICITY_PAPER}


def options(params: Parameters, numerics: Numerics = DEFAULT) -> MonitorOptions:
    """The kernel options of the parameter set's ``monitor:`` section and the Monitor step."""
    m = params.spec.monitor
    return MonitorOptions(
        SHORT_CIRCUIT_MODELS[m.short_circuit_model],
        ECCENTRICITY_MODELS[m.eccentricity_model],
        m.torque_gain_scale,
        m.commutation_loss,
        m.commutation_model == "transient",
        numerics.monitor_substeps,
    )


def run(
    params: Parameters,
    inp: Inputs,
    faults: MonitorFaults,
    numerics: Numerics = DEFAULT,
    opts: MonitorOptions | None = None,
    hinge_moment: float = 0.0,
    plant: Plant | None = None,
) -> dict[str, np.ndarray]:
    """Run the Monitor kernel (eccentricity as Z); returns trace columns.

    ``opts`` overrides the options of ``params`` and ``numerics`` (calibration);
    ``hinge_moment`` [N m] is added to the inputs' load; ``plant`` replaces the set's
    (a unit row applied with :func:`~emaprog.kernels.monitor.unit_plant`).
    """
    n = inp.time.size
    out = MonitorOutputs(np.empty(n), np.empty(n), np.empty(n), np.empty(n))
    simulate_monitor(
        inp.drive(hinge_moment),
        plant if plant is not None else params.plant,
        faults,
        opts if opts is not None else options(params, numerics),
        out,
    )
    return {"time": inp.time, "command": inp.command, **out._asdict()}


def simulate(scenario: Scenario, params: Parameters, numerics: Numerics = DEFAULT) -> Trace:
    """Simulate a scenario's true faults on the Monitor (zeta mapped through c)."""
    faults = monitor_form(flatten(scenario.faults), params.spec.monitor.eccentricity_gain)
    columns = run(params, inputs(scenario, params), faults, numerics)
    meta = provenance(
        "monitor", scenario, params, time_step=params.controller.period / numerics.monitor_substeps
    )
    return Trace(columns, meta)
