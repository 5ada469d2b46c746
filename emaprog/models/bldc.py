"""The BLDC family (six-step commutation, trapezoidal back-EMF): the first implementation of
the motor-model contract (:mod:`emaprog.models.family`). Its kernels are in
:mod:`emaprog.kernels`; this module is the only way the layers above ``models/`` reach them.
"""

from __future__ import annotations

import math

import numpy as np

from ..kernels.bldc import IDLE_PHASE, POSITIVE_PHASE
from ..kernels.control import replay_controller
from ..kernels.monitor import (
    U_HINGE_MOMENT,
    U_HINGE_STIFFNESS,
    U_PHASE_RESISTANCE,
    error_target,
    evaluate_population,
    evaluate_residuals,
    moving_average,
    simulate_monitor,
    simulate_units,
    unit_plant,
)
from ..kernels.structs import (
    UNIT_COLUMNS,
    ErrorTarget,
    MonitorOptions,
    MonitorOutputs,
    Plant,
    unit_row,
)

NAME = "bldc"

__all__ = [
    "IDLE_PHASE",
    "NAME",
    "POSITIVE_PHASE",
    "UNIT_COLUMNS",
    "U_HINGE_MOMENT",
    "U_HINGE_STIFFNESS",
    "U_PHASE_RESISTANCE",
    "ErrorTarget",
    "MonitorOptions",
    "MonitorOutputs",
    "Plant",
    "commutation_phases",
    "error_target",
    "evaluate_population",
    "evaluate_residuals",
    "moving_average",
    "replay_controller",
    "simulate_monitor",
    "simulate_units",
    "unit_plant",
    "unit_row",
]


def commutation_phases(theta_e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per electrical angle [rad], the idle winding and the one carrying the pair current
    along the torque (``s6 = floor((theta_e + pi/6) / (pi/3)) mod 6``, :mod:`~emaprog.kernels.bldc`)."""
    sector = np.floor((np.asarray(theta_e) + math.pi / 6.0) / (math.pi / 3.0)).astype(np.int64) % 6
    return IDLE_PHASE[sector], POSITIVE_PHASE[sector]
