"""NamedTuples the kernels take that are not parameter sets."""

from __future__ import annotations

from typing import NamedTuple


class FaultParams(NamedTuple):
    """Fault magnitudes as the kernels take them.

    ``ecc_magnitude`` is the air-gap reduction zeta for the Reference Model and
    the shape-function amplitude Z = c zeta for the Monitor Model.
    """

    friction: float  # [-] dry-friction multiplier k_f
    backlash: float  # [rad] total play on the output shaft
    short_a: float  # [-] shorted fraction of phase A turns
    short_b: float  # [-]
    short_c: float  # [-]
    ecc_magnitude: float  # [-] zeta (RM) or Z (MM)
    ecc_phase: float  # [rad] phi
