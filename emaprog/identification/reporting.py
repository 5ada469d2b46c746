"""The identification report's content (docs/reference.md, Identification report): the
verdict, estimates and intervals in the report's shape, the unit's form and the provenance,
with the windings named as the recording names them."""

from __future__ import annotations

import math

from .. import __version__
from ..config import parameters as parameter_sets
from ..config.parameters import Parameters
from ..config.scenario import IdentifySettings
from ..environment import environment
from ..faults import PHASE_FAULTS, QUANTITIES, nested
from . import result as verdicts
from .confidence import confidence_record


def unit_form(params: Parameters) -> dict:
    """The report's ``form``: the unit's current regulator and sensor chain, and whether the
    intervals' model-error laws were calibrated for that form (docs/reference.md,
    Confidence): the hysteresis drive with an ideal chain on the ``unit`` basis, a PWM drive
    on the ``form`` basis; a hysteresis drive logged through a chain borrows the form's."""
    sensors = params.values()["sensors"]
    chain = sorted(k for k in parameter_sets.CHAIN_KEYS if k in sensors)
    regulator = params.spec.drive.regulator
    described = f"{regulator} drive{', sensor chain ' + ', '.join(chain) if chain else ''}"
    calibrated = params.hysteresis_form or regulator == "pwm"
    if params.hysteresis_form:
        note = "the intervals' model-error laws were calibrated for this form"
    elif calibrated:
        note = (
            f"the intervals' model-error laws were calibrated for this form ({described}) on "
            f"{FORM_CALIBRATION}: a drive or logger far from those is off the calibration "
            "(docs/tutorials/rig-unit.md, The unit's form)"
        )
    else:
        note = (
            f"the intervals' model-error laws are not calibrated for this form ({described}): "
            f"those of the PWM form ({FORM_CALIBRATION}) are used, verdicts are indicative "
            "(docs/tutorials/rig-unit.md, The unit's form)"
        )
    return {"regulator": regulator, "sensor_chain": chain, "calibrated": calibrated, "note": note}


#: What the ``form`` basis' laws were calibrated on.
FORM_CALIBRATION = (
    "campaigns/calibration-pwm.yaml's units (a 20 kHz PWM drive with a PI current loop, dead "
    "time and computation delay; 2 kHz anti-alias filters; resolver speed; an aerodynamic "
    "spring)"
)


def report_data(
    result,
    *,
    settings: IdentifySettings,
    params: Parameters,
    truth: dict[str, float] | None,
    load,
    load_note: str,
    notes: dict,
    source: str,
    scenario_name: str | None,
    inspection: dict | None,
) -> dict:
    """The ``report.json`` content of one identification (docs/reference.md, Identification
    report): the verdict (:func:`~emaprog.identification.result.judge`, the same a campaign
    row takes), estimates and intervals in the report's shape, and the provenance."""
    verdict = verdicts.judge(result, settings.estimate, params, truth)
    health, error = verdict.health, verdict.error
    confidence = confidence_record(result.confidence)
    confidence["isolation"] = verdict.isolation
    return {
        "estimate": nested(result.estimate),
        "truth": nested(truth) if truth is not None else None,
        "error": nested(error) if error is not None else None,
        "health": health,
        "interval": nested(
            {
                q: list(result.confidence.interval[q]) if q in result.confidence.interval else None
                for q in QUANTITIES
            }
        ),
        **{f"{fault}_phase": verdict.phase[fault] for fault in PHASE_FAULTS},
        "nuisance": {name: result.estimate[name] for name in settings.nuisances or []},
        "nuisance_interval": {
            name: [x if math.isfinite(x) else None for x in result.confidence.interval[name]]
            for name in settings.nuisances or []
        },
        "fitness": result.fitness,
        "confidence": confidence,
        "correction": {
            "applied": result.objective.correction.applied,
            "note": result.objective.correction.note,
        },
        "load": {
            "applied": load.model_dump(mode="json") if load is not None else None,
            "note": load_note,
        },
        "defaults": notes,
        "form": unit_form(params),
        "ga": {
            "estimate": nested(result.ga_estimate),
            "fitness": result.ga_fitness,
            "generations": result.generations,
            "stopped_by": result.stopped_by,
            "refined": result.refined,
            "runs": result.runs,
            "cleared": result.cleared,
            "position_play": result.position_play,
            "seed": result.ga_seed,
            "logbook": result.logbook,
        },
        "evaluations": result.evaluations,
        "elapsed_s": result.elapsed_s,
        "seed": settings.ga.seed,
        "settings": settings.model_dump(mode="json"),
        "trace": source,
        "scenario": scenario_name,
        "parameters": params.source_file,
        "inspection": inspection,
        "emaprog_version": __version__,
        "environment": environment(),
    }


def name_phases_as_recorded(data: dict, identity: dict | None) -> None:
    """Name the windings as the recording does: the models' winding x is the recording's
    ``identity["windings"][x]`` (docs/reference.md, "Phase identity"). The report's
    per-phase values, the named phase and its isolation are renamed in place;
    ``phase_identity`` and ``phase_channels`` (recording phase -> logger column) added."""
    if identity is None:
        return
    data["phase_identity"] = identity
    if not identity["trusted"]:
        data["phase_identity"]["note"] = (
            f"the recorded phase currents could not be matched to the model's windings "
            f"(agreement {identity['agreement']:.2f}, runner-up {identity['runner_up']:.2f}): "
            "phases are named by the model's convention"
        )
        return
    rename = {w: key.removeprefix("current_") for w, key in identity["windings"].items()}
    data["phase_channels"] = {rename[w]: identity["channels"][w] for w in rename}
    if all(rename[w] == w for w in rename):
        return
    errors = data["confidence"]["standard_error"]
    for fault in PHASE_FAULTS:
        for tree in (data["estimate"], data["interval"], data["ga"]["estimate"]):
            if isinstance(tree.get(fault), dict):
                renamed = {rename[w]: v for w, v in tree[fault].items()}
                tree[fault] = {w: renamed[w] for w in sorted(renamed)}
        if data.get(f"{fault}_phase"):
            data[f"{fault}_phase"] = rename[data[f"{fault}_phase"]]
        isolation = data["confidence"]["isolation"].get(fault)
        if isolation:
            isolation["phase"], isolation["runner_up"] = (
                rename[isolation["phase"]],
                rename[isolation["runner_up"]],
            )
        if f"{fault}_a" in errors:
            errors.update({f"{fault}_{rename[w]}": errors[f"{fault}_{w}"] for w in rename})


def check_phase_identity(data: dict, params: Parameters) -> None:
    """Compare the inspection's channel-to-winding identity with the unit's commissioning
    recordings' (``phase_identity.commissioning``): a rewired or re-mapped logger is said."""
    record = params.spec.commissioning
    found = data.get("phase_identity")
    if record is None or not found or not found.get("trusted"):
        return
    known = [
        r.phase_identity
        for r in record.recordings
        if r.phase_identity and r.phase_identity.get("trusted")
    ]
    if not known:
        return
    same = all(k["channels"] == found["channels"] for k in known)
    found["commissioning"] = (
        "agrees with the unit's commissioning recordings"
        if same
        else "DIFFERS from the unit's commissioning recordings (commissioning: "
        + ", ".join(f"winding {w} on {c}" for w, c in known[0]["channels"].items())
        + "; now: "
        + ", ".join(f"winding {w} on {c}" for w, c in found["channels"].items())
        + "): the logger was rewired or the map changed; the phase is named as this "
        "recording's channels say"
    )
