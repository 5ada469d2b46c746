"""What an identification concludes: health verdicts, truth and error beside each estimate."""

from __future__ import annotations

import math

from ..faults import QUANTITIES
from ..parameters import Parameters

VERDICTS = ("nominal", "incipient", "degraded")


def severity(fault: str, values: dict[str, float]) -> float:
    """The scalar a fault's health thresholds apply to (parameter set ``health:``).

    friction: ``|k_f - 1|`` [-]; backlash [rad]; short_circuit: the largest
    shorted fraction of the three phases [-]; eccentricity: zeta [-].
    """
    if fault == "friction":
        return abs(values["friction"] - 1.0)
    if fault == "backlash":
        return values["backlash"]
    if fault == "short_circuit":
        return max(values[f"short_circuit_{x}"] for x in "abc")
    if fault == "eccentricity":
        return values["eccentricity_zeta"]
    raise KeyError(fault)


def health(values: dict[str, float], faults: list[str], params: Parameters) -> dict[str, str]:
    """Verdict per estimated fault: below ``incipient`` nominal, below ``degraded`` incipient."""
    verdicts = {}
    for fault in faults:
        limit = getattr(params.spec.health, fault)
        s = severity(fault, values)
        verdicts[fault] = ("nominal" if s < limit.incipient
                           else "incipient" if s < limit.degraded else "degraded")
    return verdicts


def faulty_phase(values: dict[str, float]) -> str | None:
    """The phase with the largest shorted fraction, or None if all are zero."""
    fractions = {x: values[f"short_circuit_{x}"] for x in "abc"}
    phase = max(fractions, key=fractions.get)
    return phase if fractions[phase] > 0 else None


def angle_difference(a: float, b: float) -> float:
    """a - b wrapped into (-pi, pi] [rad]."""
    return math.remainder(a - b, 2.0 * math.pi)


def errors(estimate: dict[str, float], truth: dict[str, float]) -> dict[str, float | None]:
    """estimate - truth per quantity; the eccentricity phase only where zeta_true > 0."""
    out: dict[str, float | None] = {}
    for name in QUANTITIES:
        if name == "eccentricity_phase":
            out[name] = (angle_difference(estimate[name], truth[name])
                         if truth["eccentricity_zeta"] > 0 else None)
        else:
            out[name] = estimate[name] - truth[name]
    return out
