"""Running one case: simulate its unit, commission it if asked, identify, and the case row (docs/reference.md, Campaign results)."""

from __future__ import annotations

import time
import traceback
from typing import NamedTuple

from ..config import parameters as parameter_sets
from ..config.parameters import Parameters
from ..config.scenario import Faults, Scenario
from ..faults import (
    FAULT_NAMES,
    PHASE_FAULTS,
    QUANTITIES,
    flatten,
    worst_phase,
)
from ..identification import identify_trace
from ..identification import result as verdicts
from ..identification.defaults import resolve as resolve_settings
from ..identification.objective import NUISANCE_DEFAULTS, ResidualRecording, recording_residual
from ..models import reference
from ..models.common import inputs, recorded_motor_angle
from .sampling import CaseSpec, with_hinge


def commission_case(
    spec: CaseSpec, unit: Parameters
) -> tuple[Parameters, dict, list[ResidualRecording]]:
    """Commission the case's unit from its own healthy recordings, as ``emaprog commission``
    does from a rig's.

    Returns the commissioned set, the row's commissioning columns (the hinge moment's and
    the spring's errors: the first recording's) and each recording's residual against the
    commissioned healthy Monitor (``identify.nominal_correction: recording`` applies their
    mean, as for a commissioned unit's file).
    """
    from ..fitting import commission as commissioning

    assert spec.commission  # the case commissions its unit
    name = f"case {spec.case_id} commissioning"
    recordings, prepared = [], []
    for k, drawn in enumerate(spec.commission):
        healthy = Scenario.model_validate(
            {
                **spec.scenario.model_dump(mode="json"),
                "faults": Faults().model_dump(mode="json"),
                "seed": drawn.seed,
            }
        )
        recording = reference.simulate(
            with_hinge(healthy, drawn.hinge_moment, drawn.hinge_stiffness), unit
        )
        source = name if k == 0 else f"{name} recording {k + 1}"
        recordings.append(recording)
        prepared.append(commissioning.prepare(recording, source, spec.params))
    fit = commissioning.fit(prepared, spec.params)  # the spring as `emaprog commission`
    commissioning.check_explained(fit, prepared)
    commissioned = parameter_sets.scaled(
        spec.params,
        {k: fit.values[k] / fit.base[k] for k in fit.values},
        f"case {spec.case_id} commissioned unit",
    )
    true = {**unit.spec.electrical.model_dump(), **unit.spec.mechanical.model_dump()}
    first = spec.commission[0]
    row: dict[str, float | str] = {
        f"commission_err_{k}": float(v / true[k] - 1.0) for k, v in fit.values.items()
    }
    row["commission_err_hinge_moment"] = float(fit.hinge_moments[0] - first.hinge_moment)
    row["commission_undetermined"] = ",".join(fit.not_determined)
    # the fit's own (linearised) relative standard errors, NaN where held: what the
    # commissioning model-error floors are calibrated from (benchmarks/commission_errors.py)
    row.update(
        {
            f"commission_se_{k}": float(fit.standard_errors[k] / v)
            if k in fit.standard_errors
            else float("nan")
            for k, v in fit.values.items()
        }
    )
    row["commission_se_hinge_moment"] = float(fit.hinge_errors[0])
    row["commission_err_hinge_stiffness"] = float(fit.hinge_stiffnesses[0] - first.hinge_stiffness)
    row["commission_se_hinge_stiffness"] = float(fit.stiffness_errors[0])
    residuals = [
        recording_residual(
            recording,
            ready.inputs,
            commissioned,
            fit.hinge_moments[k],
            ready.source,
            hinge_stiffness=fit.hinge_stiffnesses[k],
        )
        for k, (recording, ready) in enumerate(zip(recordings, prepared, strict=True))
    ]
    return commissioned, row, residuals


def run_case(spec: CaseSpec) -> dict:
    """Simulate and identify one case; the case row (docs/reference.md, Campaign results) (plain Python values).

    The trace is the case's unit (``spec.unit``) under its hinge moment; the
    identification knows neither: it starts from ``spec.params`` (or the unit it
    commissions first) and the base scenario's load.
    """
    start = time.perf_counter()
    unit = spec.unit if spec.unit is not None else spec.params
    trace = reference.simulate(
        with_hinge(spec.scenario, spec.hinge_moment, spec.hinge_stiffness), unit
    )
    simulated = time.perf_counter()
    params, recordings = spec.params, list[ResidualRecording]()
    commission_row: dict[str, float | str] = {}
    if spec.commission is not None:
        params, commission_row, recordings = commission_case(spec, unit)
    commissioned = time.perf_counter()
    # the inspection's Monitor commutates on the recorded motor angle as the rig workflow's
    # does (docs/reference.md, The models); the trace is on the scenario's grid
    inp = inputs(spec.scenario, params)
    inp = inp._replace(motor_angle=recorded_motor_angle(trace, trace.time, inp.time, 0, params))
    settings = resolve_settings(
        spec.settings,
        trace.metadata,
        params,
        real_unit=spec.unit is not None or spec.commission is not None,
        commissioned=spec.commission is not None,
    ).settings
    result = identify_trace(
        trace,
        inp,
        params,
        settings,
        show_progress=False,
        recordings=recordings,
        commissioned=spec.commission is not None,
    )
    truth = flatten(spec.scenario.faults)
    confidence = result.confidence
    verdict = verdicts.judge(result, spec.settings.estimate, spec.params, truth)
    health, error = verdict.health, verdict.error
    assert error is not None  # a case knows its truth
    true_health = verdicts.health(truth, list(FAULT_NAMES), spec.params)
    row: dict = {
        "case_id": spec.case_id,
        "healthy_case": spec.healthy,
        "noise_seed": spec.scenario.seed,
        "ga_seed": spec.settings.ga.seed,
    }
    nan = float("nan")
    for name in QUANTITIES:
        row[f"true_{name}"] = float(truth[name])
        row[f"est_{name}"] = float(result.estimate[name])
        err = error[name]
        row[f"err_{name}"] = nan if err is None else float(err)
        low, high = confidence.interval.get(name, (nan, nan))
        row[f"low_{name}"], row[f"high_{name}"] = float(low), float(high)
        row[f"se_{name}"] = float(confidence.standard_error.get(name, nan))
        row[f"sigma_{name}"] = float(confidence.linear_error.get(name, nan))
    for fault in FAULT_NAMES:
        row[f"health_{fault}"] = health.get(fault, "not estimated")
        row[f"true_health_{fault}"] = true_health[fault]
    for fault in PHASE_FAULTS:
        row[f"true_{fault}_phase"] = worst_phase(truth, fault) or "none"
        row[f"est_{fault}_phase"] = verdict.phase[fault] or "none"
    row.update(
        {
            "fitness": float(result.fitness),
            "correction": result.objective.correction.applied,
            "floor_ratio": float(confidence.floor.ratio),
            "fault_load": float(confidence.fault_load),
            "twin": bool(confidence.twin),
            # the recording's own basis, which its calibration campaign calibrates, and the
            # laws that judged it (another past that basis' explained limit)
            "basis": confidence.past_limit_of or confidence.basis,
            "laws": confidence.basis,
            "echo": bool(confidence.echo),
            **{
                f"echo_{q}": float((confidence.echo or {}).get("errors", {}).get(q, nan))
                for q in QUANTITIES
            },
            **{
                f"{fault}_isolation_confidence": float(found["confidence"]) if found else nan
                for fault, found in confidence.isolation.items()
            },
            "evaluations": int(result.evaluations),
            "generations": int(result.generations),
            "runs": int(result.runs),
            "cleared": bool(result.cleared),
            "position_play": bool(result.position_play),
            "simulate_s": simulated - start,
            "identify_s": result.elapsed_s,
            "true_hinge_moment": float(spec.hinge_moment),
            "true_hinge_stiffness": float(spec.hinge_stiffness),
            **{
                f"est_{name}": float(result.estimate[name])
                if name in (settings.nuisances or [])
                else float("nan")
                for name in NUISANCE_DEFAULTS
            },
            **{
                f"{column}_{name}": float(errors.get(name, float("nan")))
                for name in NUISANCE_DEFAULTS
                for column, errors in (
                    ("se", confidence.standard_error),
                    ("sigma", confidence.linear_error),
                )
            },
            # the winding resistance the identification should find, over the set it uses
            "true_resistance_factor": float(
                unit.spec.electrical.phase_resistance / params.spec.electrical.phase_resistance
            ),
        }
    )
    if spec.commission is not None:
        row.update(commission_row, commission_s=commissioned - simulated)
    return row


class Failure(NamedTuple):
    case_id: int
    error: str
    traceback: str


def run_case_safely(spec: CaseSpec) -> dict | Failure:
    """:func:`run_case`, with any exception turned into a :class:`Failure` record."""
    try:
        return run_case(spec)
    except Exception as exc:  # noqa: BLE001 - a failed case must not stop the campaign
        return Failure(spec.case_id, f"{type(exc).__name__}: {exc}", traceback.format_exc())
