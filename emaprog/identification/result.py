"""What an identification concludes: health verdicts, truth and error beside each estimate."""

from __future__ import annotations

import math

from ..config.parameters import Parameters
from ..faults import CATALOGUE, severity

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
