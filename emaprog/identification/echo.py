"""The method's own error under a recording's conditions: the echo twin.

The model-error laws (:mod:`.confidence`) were calibrated on recordings of the standard
test command at the shipped set's noise, explained by the Monitor about as well as the
calibration campaigns' were. A recording off those conditions - another command (a step),
more noise, a shorter test, a fit far above its noise floor - carries errors the laws never
saw: on twins driven by a 0.05 rad step a healthy backlash read 4e-5 rad every time, with
intervals a fifth of that wide; with five times the noise the Monitor (whose loop sees no
noise) misreads the dither the noise drives through the Reference's loop.

Such a recording gets an echo: the Reference Model run with the recording's own estimate
as its truth, on the recording's command, grid, load and rotor angle, with the set's
sensor noise scaled to the recording's, and identified again by the least-squares polish
from that truth (on a unit of another form, its play then read from the position as the
identification reads it, :func:`.run.play_from_position`). How far the echo's estimate lands from its truth is one draw of the
method's error under exactly these conditions; each quantity's standard error takes it in
quadrature (docs/reference.md, "Confidence"). Conditions inside the calibration keep the
laws alone, so the calibrated campaigns do not move.
"""

from __future__ import annotations

import math

import numpy as np

from ..config.parameters import Parameters
from ..config.scenario import IdentifySettings
from ..errors import past_limit
from ..faults import QUANTITIES, reference_form
from ..io.storage import Trace
from ..models import reference
from ..models.common import recorded_instants
from ..numerics import DEFAULT, Numerics
from .objective import NO_CORRECTION, NUISANCE_DEFAULTS, Objective, reference_correction

#: The noise the calibration campaigns' recordings carry, as :func:`~emaprog.signals.noise_sigma`
#: measures it (ADC step included) on the shipped set's Reference trace of the standard test
#: command: current 0.10 A (the hysteresis regulator's ripple adds to the 0.05 A sensor
#: noise), position 4.1e-5 rad, speed 0.30 rad/s.
CALIBRATED_NOISE = {"current": 0.10, "position": 4.1e-5, "speed": 0.30}
#: [-] a recording noisier than the calibration by more than this (on any recorded signal)
#: is off the calibration.
NOISE_LIMIT = 1.5
#: [s] a recording shorter than this (the standard test command is 0.5 s) is off it too.
CALIBRATED_SECONDS = 0.45
#: Noise seed of the echo's Reference run (deterministic: the same recording, the same echo).
ECHO_SEED = 20261201


def off_calibration(
    trace: Trace, noise: dict[str, float], ratio: float, ratio_limit: float
) -> list[str]:
    """Why a recording is off the conditions the model-error laws were calibrated under
    (empty: it is not). ``noise``: per signal, the recording's noise sigma; ``ratio``: its
    fit-to-floor ratio, against ``ratio_limit`` (its basis's calibration ratio)."""
    reasons = []
    if math.isfinite(ratio) and ratio > ratio_limit:
        reasons.append(
            f"fit {past_limit(ratio, ratio_limit, '.3g')} x its noise floor "
            f"(calibrated up to {ratio_limit:g} x)"
        )
    recorded = [s for s in CALIBRATED_NOISE if not (s == "speed" and _speed_derived(trace))]
    noisiest = max(recorded, key=lambda s: noise[s] / CALIBRATED_NOISE[s])
    if noise[noisiest] / CALIBRATED_NOISE[noisiest] > NOISE_LIMIT:
        reasons.append(
            f"{noisiest} noise "
            f"{past_limit(noise[noisiest] / CALIBRATED_NOISE[noisiest], NOISE_LIMIT, '.3g')} x "
            f"the calibration's (at most {NOISE_LIMIT:g} x)"
        )
    duration = float(trace.time[-1] - trace.time[0])
    if duration < CALIBRATED_SECONDS:
        reasons.append(f"{duration:.3g} s long (calibrated on {CALIBRATED_SECONDS:g} s and more)")
    return reasons


def _speed_derived(trace: Trace) -> bool:
    speed = (getattr(trace, "metadata", None) or {}).get("speed") or {}
    return speed.get("source", "recorded") != "recorded"


def _noisy_set(params: Parameters, trace: Trace, noise: dict[str, float]) -> Parameters:
    """The set with each sensor's noise scaled to the recording's (never below the set's)."""
    from ..config.parameters import ParameterFile, derive

    spec = params.spec.model_dump(mode="json")
    sensors = spec["sensors"]
    for signal, key in (
        ("position", "position_noise"),
        ("speed", "speed_noise"),
        ("current", "current_noise"),
    ):
        if signal == "speed" and _speed_derived(trace):
            continue
        ratio = noise[signal] / CALIBRATED_NOISE[signal]
        sensors[key] = sensors[key] * max(1.0, ratio)
    return derive(ParameterFile.model_validate(spec), params.source_file)


def echo_errors(
    objective: Objective,
    trace: Trace,
    estimate: dict[str, float],
    settings: IdentifySettings,
    noise: dict[str, float],
    numerics: Numerics = DEFAULT,
) -> dict[str, float]:
    """Per estimated quantity (and nuisance), the echo's estimate minus its truth (module
    docstring); the eccentricity phase as the shorter arc."""
    from ..config.parameters import scaled
    from .run import PolishCoordinates, _least_squares, form_refinement, play_from_position

    params = objective.params
    truth = {**estimate}
    unit = _noisy_set(params, trace, noise)
    factor = truth.get("resistance_factor", NUISANCE_DEFAULTS["resistance_factor"])
    if factor != 1.0:
        unit = scaled(unit, {"phase_resistance": factor}, unit.source_file)
    inputs = objective.inputs
    # the echo's truth under the estimated spring; it is identified on the recording's inputs
    spring = truth.get("hinge_stiffness", NUISANCE_DEFAULTS["hinge_stiffness"])
    columns, _ = reference.run(
        unit,
        inputs._replace(load_stiffness=inputs.load_stiffness + spring),
        reference_form({q: truth[q] for q in QUANTITIES}),
        ECHO_SEED,
        hinge_moment=float(truth.get("hinge_moment", 0.0)),
    )
    # the echo at the recording's own instants (its rate and start)
    instants = recorded_instants(trace.time, inputs.time)
    echoed = {
        name: instants.sample(np.asarray(columns[name]))
        for name in ("command", "position", "speed", "current")
    }
    echoed["time"] = np.asarray(trace.time, dtype=np.float64) - float(trace.time[0])
    echo = Trace(echoed, {"model": "echo", "speed": {"source": "recorded"}})
    applied = objective.correction.applied
    correction = (
        objective.correction
        if applied == "reference"
        else NO_CORRECTION
        if applied == "none"
        else reference_correction(inputs, params, numerics)
    )
    again = Objective(echo, inputs, params, settings, numerics, correction)
    genes, _ = _least_squares(again, PolishCoordinates(again), again.genes_for(truth))
    if form_refinement(settings, params):  # the play as identification reads it
        reread = play_from_position(again, genes)
        genes = genes if reread is None else reread
    found = again.values(genes)
    errors = {}
    for gene in again.genes:
        name = gene.quantity
        if gene.circular:
            errors[name] = (found[name] - truth[name] + math.pi) % (2.0 * math.pi) - math.pi
        else:
            errors[name] = found[name] - truth[name]
    return errors
