"""The motor-model contract: what a motor family gives the layers above ``models/``.

Identification, commissioning, calibration and the recording reader never import a
kernel: they reach the family's kernels, structs and tables through an object that
satisfies :class:`MotorFamily`, chosen by the parameter set's ``motor.family``
(:func:`family_of`). The BLDC family (:mod:`emaprog.models.bldc`) is the first; a second one
(a PMSM under field-oriented control, docs/how-to/add-a-motor-family.md) is one more module
that provides the same names.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..config.parameters import Parameters


@runtime_checkable
class MotorFamily(Protocol):
    """What a motor family provides (the BLDC module is the reference implementation)."""

    #: the parameter set's ``motor.family`` that selects it
    NAME: str
    #: the kernels' named structs
    Plant: type
    ErrorTarget: type
    MonitorOptions: type
    MonitorOutputs: type
    #: unit (commissioning) columns of a unit row, and their slots
    UNIT_COLUMNS: tuple[str, ...]
    U_HINGE_MOMENT: int
    U_HINGE_STIFFNESS: int
    U_PHASE_RESISTANCE: int

    def unit_row(
        self, plant: Any, hinge_moment: float = 0.0, hinge_stiffness: float = 0.0
    ) -> np.ndarray:
        """A plant's unit row (:data:`UNIT_COLUMNS`)."""
        ...

    def unit_plant(self, plant: Any, row: np.ndarray) -> Any:
        """The plant with a unit row's values."""
        ...

    def error_target(
        self,
        current: np.ndarray,
        position: np.ndarray,
        speed: np.ndarray,
        weights: np.ndarray,
        filter_width: int,
        sample_weight: np.ndarray,
        sample_index: np.ndarray,
        sample_fraction: np.ndarray,
    ) -> Any:
        """What a batch of Monitor runs is compared with: the measured signals with their
        centres and norms (computed once, read by every batch and by the noise floor)."""
        ...

    def simulate_monitor(self, drive: Any, plant: Any, faults: Any, options: Any, out: Any) -> None:
        """One Monitor run into preallocated outputs."""
        ...

    def simulate_units(
        self,
        row: np.ndarray,
        units: np.ndarray,
        drive: Any,
        plant: Any,
        options: Any,
        current: np.ndarray,
        position: np.ndarray,
        speed: np.ndarray,
    ) -> None:
        """The Monitor under each of a batch of unit rows (one jitted parallel call)."""
        ...

    def evaluate_population(
        self,
        faults: np.ndarray,
        units: np.ndarray,
        drive: Any,
        plant: Any,
        options: Any,
        target: Any,
        fitness: np.ndarray,
    ) -> None:
        """The fitness of a batch of candidate fault rows (one jitted parallel call)."""
        ...

    def evaluate_residuals(
        self,
        faults: np.ndarray,
        units: np.ndarray,
        drive: Any,
        plant: Any,
        options: Any,
        target: Any,
        residuals: np.ndarray,
    ) -> None:
        """The weighted residual vectors of a batch of candidates (one jitted call)."""
        ...

    def moving_average(self, x: np.ndarray, width: int, out: np.ndarray) -> None:
        """The error's centred moving average (the same on both grids)."""
        ...

    def replay_controller(
        self,
        command: np.ndarray,
        position: np.ndarray,
        speed: np.ndarray,
        controller: Any,
        demand: np.ndarray,
    ) -> None:
        """The actuator's own current demand on recorded signals (signs a current built
        from phase currents)."""
        ...

    def commutation_phases(self, theta_e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per electrical angle, the idle winding and the one carrying the torque's current
        (phase identity of a recording)."""
        ...


def family_of(params: Parameters | None = None) -> ModuleType:
    """The motor family of a parameter set (``motor.family``; ``bldc`` when not given)."""
    from . import bldc

    name = "bldc" if params is None else params.spec.motor.family
    families = {bldc.NAME: bldc}
    family = families[name]
    assert isinstance(family, MotorFamily)
    return family
