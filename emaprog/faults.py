"""The fault catalogue: names, units, healthy values, and their kernel form."""

from __future__ import annotations

from .kernels.structs import FaultParams
from .scenario import Faults

__all__ = ["FaultParams", "HEALTHY", "QUANTITIES", "flatten", "nested", "to_params"]


#: Every scalar fault quantity: (unit, healthy value). Names as in SPEC 6 columns.
QUANTITIES: dict[str, tuple[str, float]] = {
    "friction": ("-", 1.0),
    "backlash": ("rad", 0.0),
    "short_circuit_a": ("-", 0.0),
    "short_circuit_b": ("-", 0.0),
    "short_circuit_c": ("-", 0.0),
    "eccentricity_zeta": ("-", 0.0),
    "eccentricity_phase": ("rad", 0.0),
}

HEALTHY = FaultParams(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def to_params(faults: Faults, eccentricity_gain: float = 1.0) -> FaultParams:
    """Kernel form of a scenario's faults; ``eccentricity_gain`` maps zeta to Z."""
    sc, ecc = faults.short_circuit, faults.eccentricity
    return FaultParams(float(faults.friction), float(faults.backlash), float(sc.a), float(sc.b),
                       float(sc.c), float(eccentricity_gain * ecc.zeta), float(ecc.phase))


def flatten(faults: Faults) -> dict[str, float]:
    """Scalar quantities of a Faults model, keyed as :data:`QUANTITIES`."""
    sc, ecc = faults.short_circuit, faults.eccentricity
    return {
        "friction": faults.friction, "backlash": faults.backlash,
        "short_circuit_a": sc.a, "short_circuit_b": sc.b, "short_circuit_c": sc.c,
        "eccentricity_zeta": ecc.zeta, "eccentricity_phase": ecc.phase,
    }


def nested(values: dict[str, float]) -> dict:
    """SPEC 5 report shape from flat quantities."""
    return {
        "friction": values["friction"],
        "backlash": values["backlash"],
        "short_circuit": {x: values[f"short_circuit_{x}"] for x in "abc"},
        "eccentricity": {"zeta": values["eccentricity_zeta"], "phase": values["eccentricity_phase"]},
    }
