"""Numerical method: time steps of the models. Kept apart from physical parameters."""

from __future__ import annotations

from typing import NamedTuple


class Numerics(NamedTuple):
    """Integration steps per controller period for each model."""

    reference_substeps: int = 100  # 1 us at 10 kHz: resolves the hysteresis ripple
    monitor_substeps: int = 4  # 25 us at 10 kHz: 25x the Reference step


DEFAULT = Numerics()
