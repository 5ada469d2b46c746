"""Reference Model runner: scenario + parameter set -> measured trace."""

from __future__ import annotations

import numpy as np

from .. import progress
from ..config.parameters import Parameters
from ..config.scenario import Scenario
from ..faults import FaultParams, flatten, reference_form
from ..io.storage import Trace
from ..kernels.reference import ENERGY_SLOTS, initial_state, simulate_reference
from ..kernels.structs import ReferenceOutputs, SensorNoise
from ..numerics import DEFAULT, Numerics
from .common import Inputs, inputs, provenance


def noise(params: Parameters, n: int, seed: int, enabled: bool = True) -> SensorNoise:
    """Electrical noise on the signal lines, drawn from the scenario seed."""
    s = params.spec.sensors
    if not enabled:
        zero = np.zeros(n)
        return SensorNoise(zero, zero, zero, zero, zero, zero)
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    draws = rng.standard_normal((n, 6))
    currents = draws[:, 2:] * s.current_noise
    return SensorNoise(
        draws[:, 0] * s.position_noise,
        draws[:, 1] * s.speed_noise,
        *(np.ascontiguousarray(currents[:, j]) for j in range(4)),
    )


#: Integration steps above which a run takes about a second or more (0.2 us per step):
#: only such runs draw a progress bar.
PROGRESS_STEPS = 5_000_000
CHUNKS = 50  # kernel calls of a run with a progress bar (the state carries over exactly)


def run(
    params: Parameters,
    inp: Inputs,
    faults: FaultParams,
    seed: int = 0,
    with_noise: bool = True,
    numerics: Numerics = DEFAULT,
    show_progress: bool = False,
    hinge_moment: float = 0.0,
):
    """Run the kernel; returns (columns dict, energy ledger dict).

    ``hinge_moment`` [N m] is a constant hinge moment added to the inputs' load.

    With ``show_progress`` a run long enough to be waited for is computed in
    chunks behind a progress bar; the numbers are the same either way.
    """
    n = inp.time.size
    line_noise = noise(params, n, seed, with_noise)
    out = ReferenceOutputs(*(np.empty(n) for _ in ReferenceOutputs._fields))
    energy = np.zeros(len(ENERGY_SLOTS))
    state = initial_state()
    long_run = show_progress and n * numerics.reference_substeps >= PROGRESS_STEPS
    bounds = np.linspace(0, n, CHUNKS + 1 if long_run else 2).round().astype(int)
    drive, plant = inp.drive(hinge_moment), params.plant
    with progress.task("reference model", n, long_run) as advance:
        for start, stop in zip(bounds[:-1], bounds[1:]):
            simulate_reference(
                drive,
                line_noise,
                plant,
                faults,
                numerics.reference_substeps,
                out,
                energy,
                state,
                int(start),
                int(stop),
            )
            advance(int(stop - start))
    columns = {"time": inp.time, "command": inp.command, **out._asdict()}
    return columns, dict(zip(ENERGY_SLOTS, energy.tolist()))


def simulate(
    scenario: Scenario,
    params: Parameters,
    with_noise: bool = True,
    numerics: Numerics = DEFAULT,
    show_progress: bool = False,
) -> Trace:
    """Simulate a scenario on the Reference Model and return the measured trace."""
    columns, _ = run(
        params,
        inputs(scenario, params),
        reference_form(flatten(scenario.faults)),
        scenario.seed,
        with_noise,
        numerics,
        show_progress,
    )
    meta = provenance(
        "reference",
        scenario,
        params,
        noise=with_noise,
        time_step=params.controller.period / numerics.reference_substeps,
    )
    return Trace(columns, meta)
