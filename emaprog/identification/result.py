"""What an identification concludes: health verdicts, truth and error beside each estimate."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

from ..config.parameters import Parameters
from ..faults import CATALOGUE, PHASE_FAULTS, severity

if TYPE_CHECKING:
    from .run import Identification

VERDICTS = ("nominal", "incipient", "degraded", "inconclusive")


def health(
    values: dict[str, float],
    faults: list[str],
    params: Parameters,
    inconclusive: dict[str, str] | None = None,
) -> dict[str, str]:
    """Verdict per estimated fault: below ``incipient`` nominal, below ``degraded`` incipient;
    ``inconclusive`` for the faults the recording cannot tell (their reasons' keys)."""
    verdicts = {}
    for fault in faults:
        if inconclusive and fault in inconclusive:
            verdicts[fault] = "inconclusive"
            continue
        limit = getattr(params.spec.health, fault)
        s = severity(fault, values)
        verdicts[fault] = (
            "nominal" if s < limit.incipient else "incipient" if s < limit.degraded else "degraded"
        )
    return verdicts


def angle_difference(a: float, b: float) -> float:
    """a - b wrapped into (-pi, pi] [rad]."""
    return math.remainder(a - b, 2.0 * math.pi)


def errors(estimate: dict[str, float], truth: dict[str, float]) -> dict[str, float | None]:
    """estimate - truth per quantity; an angle (wrapped) only where its fault is truly present."""
    out: dict[str, float | None] = {}
    for fault in CATALOGUE:
        present = severity(fault.name, truth) > 0
        for q in fault.quantities:
            if q.circular:
                out[q.name] = angle_difference(estimate[q.name], truth[q.name]) if present else None
            else:
                out[q.name] = estimate[q.name] - truth[q.name]
    return out


class Verdict(NamedTuple):
    """What one identification concludes, the same for a report and a campaign row."""

    health: dict[str, str]  # per estimated fault (:data:`VERDICTS`)
    error: dict[str, float | None] | None  # estimate - truth per quantity (a twin), else None
    phase: dict[str, str | None]  # per-phase fault -> the phase named faulty, or None
    #: per-phase fault -> its phase's confidence against the runner-up (None unless flagged)
    isolation: dict[str, dict | None]


def judge(
    result: Identification,
    estimated: list[str],
    params: Parameters,
    truth: dict[str, float] | None = None,
) -> Verdict:
    """The :class:`Verdict` of an identification: health per estimated fault under the set's
    thresholds (``inconclusive`` where the recording cannot tell), the error against a known
    truth, and each per-phase fault's faulty phase with its confidence only beside its
    flagged verdict, or as the suspect phase beside an ``inconclusive`` one at its threshold
    (:func:`~emaprog.identification.confidence.named_phase`)."""
    from .confidence import named_phase

    confidence = result.confidence
    verdicts = health(result.estimate, estimated, params, confidence.inconclusive)
    phase, isolation = {}, {}
    for fault in PHASE_FAULTS:
        flagged = verdicts.get(fault) in ("incipient", "degraded")
        suspect = verdicts.get(fault) == "inconclusive" and fault in confidence.at_threshold
        found = confidence.isolation.get(fault)
        phase[fault] = named_phase(
            result.estimate, fault, flagged, found, confidence.basis, suspect
        )
        isolation[fault] = found if flagged or suspect else None
    return Verdict(
        verdicts,
        errors(result.estimate, truth) if truth is not None else None,
        phase,
        isolation,
    )
