"""Write the example rig folder: logger CSV files of one unit, as a rig's data logger writes them.

The unit is not the shipped parameter set: it is ``default`` moved by ordinary build
tolerances (``UNIT`` below). Two recordings of it while healthy, under 20 and 40 N m of
hinge moment, commission it; three inspections at 500, 1000 and 1500 flight hours, under
30 N m, carry a growing dry-friction increase and a growing short circuit of phase B.
Every file is our Reference Model's noisy trace of the standard test command
(``test-command.yaml``), written in the logger's own names, units and layout: two free-text
lines above the header, a units row below it, times in ms, angles in degrees, motor speed
in rpm, phase currents in mA (no equivalent current, no torque).

Run from the repository root: ``python examples/rig/generate.py``. The files are
deterministic (fixed noise seeds); ``truth.json`` says what each one holds.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from emaprog.config import parameters
from emaprog.config.parameters import ParameterFile, derive
from emaprog.config.scenario import load_scenario
from emaprog.faults import flatten, reference_form
from emaprog.models import reference
from emaprog.models.common import Inputs, inputs

HERE = Path(__file__).resolve().parent
#: The unit: factors on the shipped set's values (within the build tolerances (docs/reference.md, Campaign YAML)).
UNIT = {
    "motor_inertia": 1.06,
    "surface_inertia": 0.95,
    "motor_viscous": 1.2,
    "static_friction": 1.08,
    "dynamic_friction": 1.05,
    "phase_resistance": 1.05,
    "back_emf_constant": 0.98,
    "phase_inductance": 1.04,
    "transmission_stiffness": 0.9,
}
ELECTRICAL = ("phase_resistance", "back_emf_constant", "phase_inductance")
#: file -> (hinge moment [N m], faults, noise seed, usage [h] or None)
RECORDINGS = {
    "healthy-20Nm.csv": (20.0, {}, 11, None),
    "healthy-40Nm.csv": (40.0, {}, 12, None),
    "inspection-0500h.csv": (30.0, {"friction": 1.12}, 21, 500.0),
    "inspection-1000h.csv": (
        30.0,
        {"friction": 1.3, "short_circuit": {"a": 0.0, "b": 0.06, "c": 0.0}},
        22,
        1000.0,
    ),
    "inspection-1500h.csv": (
        30.0,
        {"friction": 1.5, "short_circuit": {"a": 0.0, "b": 0.12, "c": 0.0}},
        23,
        1500.0,
    ),
}
PREAMBLE = (
    "Rig EMA-7 bench 2, logger DL-400 v3.2",
    "Test: standard chirp 0.05 rad 0.5-10 Hz, 10 kHz",
)
HEADER = ("Time_ms", "Cmd_deg", "Pos_deg", "MotSpd_rpm", "Ia_mA", "Ib_mA", "Ic_mA")
UNITS_ROW = ("ms", "deg", "deg", "rpm", "mA", "mA", "mA")


def unit_parameters():
    spec = parameters.load("default").spec.model_dump()
    for name, factor in UNIT.items():
        spec["electrical" if name in ELECTRICAL else "mechanical"][name] *= factor
    spec["name"] = "ema-7-truth"
    return derive(ParameterFile.model_validate(spec), "ema-7 (true values, examples/rig)")


def simulate_recording(
    hinge: float,
    faults: dict,
    seed: int,
    preroll: float = 0.0,
    unit=None,
    electrical_angle: float = 0.0,
    spring: float = 0.0,
) -> dict[str, np.ndarray]:
    """The unit's noisy Reference trace of the standard test command under ``hinge`` [N m];
    with ``preroll`` [s] the logger starts that long before the command (the actuator at rest
    under its load from the first sample, as on a rig); ``electrical_angle`` [rad] is the
    rotor's electrical angle where the position and motor-angle sensors read 0; ``spring`` [N m/rad] an
    aerodynamic spring on the surface beside the constant ``hinge``."""
    base = load_scenario(HERE / "test-command.yaml")
    unit = unit_parameters() if unit is None else unit
    scenario = base.model_validate(
        {
            **base.model_dump(mode="json"),
            "seed": seed,
            "load": {"kind": "spring", "stiffness": spring, "torque": hinge}
            if spring
            else {"kind": "constant", "torque": hinge},
            "faults": faults,
        }
    )
    inp = inputs(scenario, unit)
    if preroll > 0.0:
        rate = unit.spec.controller.rate
        k = int(round(preroll * rate))
        n = inp.time.size + k
        inp = Inputs(
            np.arange(n) / rate,
            np.concatenate([np.full(k, inp.command[0]), inp.command]),
            np.concatenate([np.full(k, inp.load_torque[0]), inp.load_torque]),
            inp.load_stiffness,
        )
    inp = inp._replace(electrical_angle=electrical_angle)
    columns, _ = reference.run(unit, inp, reference_form(flatten(scenario.faults)), seed)
    return columns


def logger_rows(trace) -> list[str]:
    """The trace in the logger's units and number formats."""
    deg = 180.0 / math.pi
    columns = (
        trace["time"] * 1e3,
        trace["command"] * deg,
        trace["position"] * deg,
        trace["speed"] * 60.0 / (2.0 * math.pi),
        trace["current_a"] * 1e3,
        trace["current_b"] * 1e3,
        trace["current_c"] * 1e3,
    )
    formats = ("{:.1f}", "{:.5f}", "{:.5f}", "{:.1f}", "{:.0f}", "{:.0f}", "{:.0f}")
    return [",".join(f.format(v) for f, v in zip(formats, row)) for row in zip(*columns)]


def write_csv(path: Path, trace) -> None:
    lines = [*PREAMBLE, ",".join(HEADER), ",".join(UNITS_ROW), *logger_rows(trace)]
    path.write_text("\n".join(lines) + "\n")


def main() -> None:
    unit = unit_parameters()
    truth = {"unit_factors": UNIT, "recordings": {}}
    for name, (hinge, faults, seed, usage) in RECORDINGS.items():
        trace = simulate_recording(hinge, faults, seed, unit=unit)
        write_csv(HERE / name, trace)
        truth["recordings"][name] = {
            "hinge_moment": hinge,
            "faults": faults,
            "usage": usage,
            "noise_seed": seed,
        }
        print(f"{name}: {trace['time'].size} rows, hinge {hinge} N m, faults {faults}")
    (HERE / "truth.json").write_text(json.dumps(truth, indent=2) + "\n")


if __name__ == "__main__":
    main()
