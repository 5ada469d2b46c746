"""What the Reference and Monitor runners share: inputs on the grid and provenance."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .. import __version__, signals
from ..config.parameters import Parameters
from ..config.scenario import Scenario
from ..kernels.structs import Drive

#: The Drive's ``motor_angle`` when the Monitor commutates on its own angle.
NO_ANGLE = np.empty(0)


class Inputs(NamedTuple):
    """Operating inputs sampled on the controller grid."""

    time: np.ndarray  # [s]
    command: np.ndarray  # [rad]
    load_torque: np.ndarray  # [N m]
    load_stiffness: float  # [N m/rad]
    lead: int = 0  # samples before the recording's first one (time < 0): the models settle
    electrical_angle: float = 0.0  # [rad] the rotor's electrical angle at the grid's first sample
    motor_angle: np.ndarray | None = None  # [rad] recorded, on the grid (NaN: not recorded)

    def drive(self, hinge_moment: float = 0.0) -> Drive:
        """The kernels' :class:`~emaprog.kernels.structs.Drive`, plus a constant hinge moment [N m]."""
        return Drive(
            self.command,
            self.load_torque,
            float(self.load_stiffness),
            float(hinge_moment),
            float(self.electrical_angle),
            NO_ANGLE if self.motor_angle is None else self.motor_angle,
        )


def inputs(scenario: Scenario, params: Parameters) -> Inputs:
    t = signals.time_grid(scenario.duration, params.spec.controller.rate)
    cmd = signals.command(scenario.command, t, scenario.duration)
    torque, stiffness = signals.load(scenario.load, t)
    return Inputs(t, cmd, torque, stiffness)


#: [s] the models run at the recording's first command before its first sample when the
#: unit was not at rest unloaded at zero there (:func:`settle_lead`): several time constants
#: of the position loop (60 rad/s) and the speed loop's integrator.
SETTLE_SECONDS = 0.25


def starts_loaded(trace) -> bool:
    """Whether the current over the first millisecond is a holding current: its mean
    magnitude over 4 noise sigmas (noise alone averages 0.8 sigma) and over 5 % of the
    recording's RMS current. The magnitude, since the sign of an equivalent current built
    from phase currents is least sure at rest."""
    current = np.asarray(trace["current"], dtype=np.float64)
    time = np.asarray(trace.time, dtype=np.float64)
    n = signals.head_samples(time)
    head = float(np.mean(np.abs(current[:n])))
    sigma = signals.noise_sigma(current, 0.0)
    return head > max(4.0 * sigma, 0.05 * float(np.sqrt(np.mean(current**2))))


def settle_lead(trace, rate: float) -> int:
    """Controller periods the models run before a recording's first sample [-].

    Both models start at rest, unloaded, at angle 0. A twin (emaprog's own trace) and a
    rig recording whose logger starts with the test, unit at rest at 0 and its load taken
    up in the first milliseconds, start the same way: no lead. A recording whose unit
    already holds its load at the first sample (a logger started during a pre-roll at rest,
    :func:`starts_loaded`) or rests at another angle (the command's first value) is met by
    :data:`SETTLE_SECONDS` at that first command first, so that the models start from the
    unit's state.
    """
    meta = getattr(trace, "metadata", None) or {}
    if meta.get("model") in ("reference", "monitor"):
        return 0
    command = np.asarray(trace["command"], dtype=np.float64)
    position = np.asarray(trace["position"], dtype=np.float64)
    span = max(float(np.ptp(command)), 1e-9)
    n = signals.head_samples(trace.time)
    at_command = abs(float(np.mean(position[:n])) - float(command[0])) <= max(
        0.01 * span, 5.0 * signals.noise_sigma(position, 0.0) / math.sqrt(n)
    )
    at_zero = abs(float(command[0])) <= 1e-3 * span
    if not at_command or (at_zero and not starts_loaded(trace)):
        return 0  # at rest unloaded at zero, or not yet at its first command (a step at 0)
    return int(round(SETTLE_SECONDS * rate))


def inputs_from_trace(trace, params: Parameters, load_spec=None) -> Inputs:
    """Inputs on the controller grid of ``params`` for a measured trace at any rate.

    The trace's first sample is time 0; the models start at rest there, or
    :func:`settle_lead` periods before it at the first command. When the trace is already
    on the controller grid its command is used as it is; otherwise the command is
    interpolated linearly onto the grid, which covers the last recorded instant. The load
    is the scenario's where known, else none. The rotor starts at the electrical angle the
    recording's phase currents show (a trusted ``phase_identity``, docs/reference.md "Phase
    identity"), else at electrical zero; with a lead, the models' travel to the first
    command (``P N`` times its position) is taken off.
    """
    rate = params.spec.controller.rate
    t_rec = np.asarray(trace.time, dtype=np.float64) - float(trace.time[0])
    grid = signals.covering_grid(float(t_rec[-1]), rate)
    command = np.asarray(trace["command"], dtype=np.float64)
    if grid.size == t_rec.size and np.allclose(grid, t_rec, rtol=0.0, atol=1e-9 / rate):
        grid, command = t_rec, np.ascontiguousarray(command)
    else:
        command = np.interp(grid, t_rec, command)
    lead = settle_lead(trace, rate)
    identity = (getattr(trace, "metadata", None) or {}).get("phase_identity") or {}
    angle = math.radians(identity["electrical_angle_deg"]) if identity.get("trusted") else 0.0
    if lead:
        grid = np.concatenate([(np.arange(lead, dtype=np.float64) - lead) / rate, grid])
        command = np.concatenate([np.full(lead, command[0]), command])
        if angle:
            turns = params.spec.electrical.pole_pairs * params.spec.mechanical.gear_ratio
            angle -= turns * float(np.asarray(trace["position"], dtype=np.float64)[0])
    motor = recorded_motor_angle(trace, t_rec, grid, lead, params)
    if load_spec is None:
        return Inputs(grid, command, np.zeros(grid.size), 0.0, lead, angle, motor)
    torque, stiffness = signals.load(load_spec, grid)
    return Inputs(grid, command, torque, stiffness, lead, angle, motor)


def recorded_motor_angle(
    trace, t_rec: np.ndarray, grid: np.ndarray, lead: int, params: Parameters
) -> np.ndarray | None:
    """The recorded motor angle on the grid in the models' convention, or None: what the
    Monitor commutates on for a unit of another form than the hysteresis one.

    The drive commutates on its own angle sensor (docs/reference.md, "The models"). On the
    PWM form a Monitor on its own angle is off the unit's by the small differences of the
    motor's travel its form leaves (+/-0.006 rad of motor angle measured on a PWM unit with
    its true values: commutations up to 80 us apart, each a 1-2 A current residual that does
    not carry from one load to another); on the hysteresis form, whose Monitor matches the
    Reference's, its own commutations inform the fit (commissioning a perturbed unit,
    noise-free: transmission stiffness within 0.2 % on its own angle, 2.2 % on the
    recorded one; k_e 1.2 % and 1.5 %), so it keeps them. The models' motor angle starts at
    0 on the grid's first instant; the recording's first sample is at its own angle there,
    or, with a lead, at the first position times the gear ratio (where the models travel
    to). Lead instants are NaN: there the Monitor commutates on its own angle."""
    if params.hysteresis_form or "motor_angle" not in getattr(trace, "columns", {}):
        return None
    measured = np.asarray(trace["motor_angle"], dtype=np.float64)
    relative = np.interp(grid[lead:], t_rec, measured - measured[0])
    if lead:
        gear = params.spec.mechanical.gear_ratio
        relative = relative + gear * float(np.asarray(trace["position"], dtype=np.float64)[0])
        relative = np.concatenate([np.full(lead, np.nan), relative])
    return np.ascontiguousarray(relative)


class Instants(NamedTuple):
    """Where recorded samples fall on the controller grid: ``t = (index + fraction) / rate``."""

    index: np.ndarray  # type: ignore[assignment]  # (n_rec,) int64, grid sample at or before each recorded instant (shadows tuple.index)
    fraction: np.ndarray  # (n_rec,) float64 in [0, 1): the way to the next grid sample

    def sample(self, x: np.ndarray) -> np.ndarray:
        """A controller-grid signal at the recorded instants (linear interpolation)."""
        nxt = np.minimum(self.index + 1, x.size - 1)
        return np.where(
            self.fraction == 0.0,
            x[self.index],
            x[self.index] + self.fraction * (x[nxt] - x[self.index]),
        )


def recorded_instants(trace_time: np.ndarray, grid: np.ndarray, shift: float = 0.0) -> Instants:
    """The :class:`Instants` of a trace's samples, moved by ``shift`` [s], on a controller grid
    starting at 0 (or, with a lead, ``grid[0] < 0``)."""
    t_rec = np.asarray(trace_time, dtype=np.float64) - float(trace_time[0]) + shift
    if grid.size == t_rec.size and np.array_equal(grid, t_rec):
        return Instants(np.arange(grid.size, dtype=np.int64), np.zeros(grid.size))
    period = grid[1] - grid[0]
    # instants outside the grid (a shift at either end) read its first or last sample; a grid
    # with a lead (Inputs.lead) starts before the recording's first sample
    position = np.clip((t_rec - grid[0]) / period, 0.0, grid.size - 1.0)
    index = np.minimum(np.floor(position + 1e-9).astype(np.int64), grid.size - 1)
    fraction = np.clip(position - index, 0.0, 1.0)
    fraction[(np.abs(fraction) < 1e-9) | (index == grid.size - 1)] = 0.0
    return Instants(index, fraction)


def provenance(model: str, scenario: Scenario, params: Parameters, **extra) -> dict:
    """The ``emaprog`` metadata of a trace (docs/reference.md, Traces)."""
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
