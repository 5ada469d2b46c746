"""The named structs the kernels take: parameters, inputs, faults, options, outputs.

numba compiles NamedTuples field by field, so every kernel argument has a name
and a unit here and no kernel unpacks an anonymous tuple or slot index. The
parameter structs are built from a validated parameter set by
:func:`emaprog.config.parameters.derive`; the others by the model runners.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

# ---------------------------------------------------------------- parameters
#: The current regulators, in the order of ``ElectricalParams.regulator``
#: (:mod:`emaprog.kernels.drive`).
REGULATORS = ("hysteresis", "pwm")


class ElectricalParams(NamedTuple):
    dc_bus_voltage: float  # [V]
    pole_pairs: float  # [-]
    phase_resistance: float  # [ohm]
    phase_inductance: float  # [H]
    back_emf_constant: float  # [V s/rad] per phase
    current_limit: float  # [A]
    hysteresis_band: float  # [A]
    regulator: int  # index in REGULATORS
    pwm_period: float  # [s] derived: 1 / pwm_frequency
    dead_time: float  # [s]
    loop_gain: float  # [V/A] PI proportional gain on the pair current
    loop_integral: float  # [V/(A s)] PI integral gain
    emf_feedforward: float  # [V s/rad] pair back-EMF feed-forward gain (0: none)
    loop_delay: int  # [PWM periods] from the current sample to its duty


class MechanicalParams(NamedTuple):
    motor_inertia: float  # [kg m^2]
    motor_viscous: float  # [N m s/rad]
    static_friction: float  # [N m]
    dynamic_friction: float  # [N m]
    gear_ratio: float  # [-]
    surface_inertia: float  # [kg m^2]
    surface_damping: float  # [N m s/rad]
    transmission_stiffness: float  # [N m/rad]
    transmission_damping: float  # [N m s/rad]
    end_stop: float  # [rad]
    end_stop_stiffness: float  # [N m/rad]
    end_stop_damping: float  # [N m s/rad]


class ControllerParams(NamedTuple):
    period: float  # [s] derived: 1 / rate
    position_gain: float
    position_integral: float
    speed_gain: float
    speed_integral: float
    speed_limit: float
    current_limit: float  # [A] copied from electrical: the loop saturates I_ref


class SensorParams(NamedTuple):
    position_offset: float  # [rad]
    position_lsb: float  # [rad] derived: 2 range / 2^bits
    speed_lsb: float  # [rad/s] derived
    current_lsb: float  # [A] derived
    position_range: float  # [rad]
    speed_range: float  # [rad/s]
    current_range: float  # [A]
    position_cutoff: float  # [rad/s] anti-alias filter (0: none)
    position_order: int  # [-] 1 or 2 (Butterworth)
    speed_cutoff: (
        float  # [rad/s] tachometer anti-alias, or the digital filter on the angle's difference
    )
    speed_order: int  # [-]
    current_cutoff: float  # [rad/s] each current line's anti-alias filter
    current_order: int  # [-]
    speed_from_angle: bool  # speed differenced from the resolver's motor angle
    angle_lsb: float  # [rad] resolver step: 2 pi / 2^angle_bits
    current_point: bool  # currents point-sampled at k T (else their mean over the period)
    current_gain_a: float  # [-] phase-current channels as the logger reads them:
    current_gain_b: float  #     gain x current + offset
    current_gain_c: float
    current_offset_a: float  # [A]
    current_offset_b: float
    current_offset_c: float


class FilterCoefficients(NamedTuple):
    """One sensor-chain filter discretised at a model's step (:mod:`emaprog.kernels.sensors`):
    ``x' = A_d x + B_d u``, output ``x[0]``."""

    a00: float
    a01: float
    a10: float
    a11: float
    b0: float
    b1: float
    on: bool  # False: the line has no filter (its output is its input)


class ChainState(NamedTuple):
    """The sensor chain's filter states outside the current lines [their signal's unit, and
    per second]: position and tachometer anti-alias filters, the digital speed filter, and
    the resolver's last reading of the motor angle [rad]."""

    position: float
    position_rate: float
    speed: float
    speed_rate: float
    digital: float
    digital_rate: float
    resolver: float


class Plant(NamedTuple):
    """One actuator unit: motor and drive, transmission, controller, sensors."""

    electrical: ElectricalParams
    mechanical: MechanicalParams
    controller: ControllerParams
    sensors: SensorParams


#: Columns of a per-candidate unit row (:func:`emaprog.kernels.monitor.evaluate_population`):
#: the physical values that vary from unit to unit, and the recording's constant hinge
#: moment and aerodynamic spring (both added to the drive's load). Units: kg m^2, kg m^2,
#: N m s/rad, N m, N m, ohm, V s/rad, H, N m/rad, N m, N m/rad.
UNIT_COLUMNS = (
    "motor_inertia",
    "surface_inertia",
    "motor_viscous",
    "static_friction",
    "dynamic_friction",
    "phase_resistance",
    "back_emf_constant",
    "phase_inductance",
    "transmission_stiffness",
    "hinge_moment",
    "hinge_stiffness",
)


def unit_row(plant: Plant, hinge_moment: float = 0.0, hinge_stiffness: float = 0.0) -> np.ndarray:
    """The :data:`UNIT_COLUMNS` row of a plant as it is [SI]."""
    e, m = plant.electrical, plant.mechanical
    return np.array(
        [
            m.motor_inertia,
            m.surface_inertia,
            m.motor_viscous,
            m.static_friction,
            m.dynamic_friction,
            e.phase_resistance,
            e.back_emf_constant,
            e.phase_inductance,
            m.transmission_stiffness,
            hinge_moment,
            hinge_stiffness,
        ]
    )


# ---------------------------------------------------------------- inputs
class Drive(NamedTuple):
    """Operating inputs on the controller grid: the command and the hinge moment."""

    command: np.ndarray  # (n,) [rad] surface position command
    load_torque: np.ndarray  # (n,) [N m] hinge moment opposing +deflection
    load_stiffness: float  # [N m/rad] aerodynamic spring
    load_offset: float  # [N m] constant hinge moment added to load_torque (a nuisance)
    electrical_angle: (
        float  # [rad] rotor electrical angle at the first sample (0: at electrical zero)
    )
    #: (n,) [rad] the recorded motor angle on the grid, from 0 at the first sample (NaN
    #: where not recorded), that the Monitor commutates on; (0,): its own angle
    motor_angle: np.ndarray


class SensorNoise(NamedTuple):
    """Electrical noise on the signal lines, drawn outside the kernels (one value per period)."""

    position: np.ndarray  # (n,) [rad]
    speed: np.ndarray  # (n,) [rad/s]
    current: np.ndarray  # (n,) [A] equivalent-current line
    current_a: np.ndarray  # (n,) [A]
    current_b: np.ndarray  # (n,) [A]
    current_c: np.ndarray  # (n,) [A]


# ---------------------------------------------------------------- faults
class FaultParams(NamedTuple):
    """Fault magnitudes in physical form (Reference Model)."""

    friction: float  # [-] dry-friction multiplier k_f
    backlash: float  # [rad] total play on the output shaft
    short_a: float  # [-] shorted fraction of phase A turns
    short_b: float  # [-]
    short_c: float  # [-]
    eccentricity_zeta: float  # [-] air-gap reduction / nominal gap
    eccentricity_phase: float  # [rad] phi


class MonitorFaults(NamedTuple):
    """Fault magnitudes in the Monitor's form: eccentricity as the shape amplitude Z = c zeta."""

    friction: float  # [-]
    backlash: float  # [rad]
    short_a: float  # [-]
    short_b: float  # [-]
    short_c: float  # [-]
    eccentricity_z: float  # [-] Z of the RE shape function
    eccentricity_phase: float  # [rad]


# ---------------------------------------------------------------- options
class MonitorOptions(NamedTuple):
    """How the Monitor is built: fault laws, calibrated equivalents, numerical step."""

    short_circuit_model: int  # SHORT_CIRCUIT_MODULATED | SHORT_CIRCUIT_AVERAGED
    eccentricity_model: int  # ECCENTRICITY_PAIR | ECCENTRICITY_PAPER
    torque_gain_scale: float  # [-] nominal torque/back-EMF gain correction
    commutation_loss: float  # [s/rad] torque-per-ampere drop with speed
    commutation: bool  # model the outgoing phase's freewheeling after each sector change
    substeps: int  # integration steps per controller period


class ErrorTarget(NamedTuple):
    """What a batch of Monitor runs is compared with (identification, calibration, commissioning).

    The measured signals are at the recording's own instants (n_rec of them, any
    rate); the Monitor runs on the controller grid, is low-passed there with
    ``filter_width`` and read at each recorded instant
    ``(sample_index + sample_fraction) / rate`` by linear interpolation. ``centres`` and
    ``norms`` follow from the signals: build it with ``kernels.monitor.error_target``.
    """

    current: np.ndarray  # (n_rec,) [A] measured, low-passed over the same 1 ms
    position: np.ndarray  # (n_rec,) [rad]
    speed: np.ndarray  # (n_rec,) [rad/s]
    weights: np.ndarray  # (3,) [-] of the normalised current, position, speed errors
    filter_width: int  # [grid samples] centred moving average applied to the Monitor's signals
    sample_weight: np.ndarray  # (n_rec,) [-] weight of each sample (0 leaves it out)
    sample_index: np.ndarray  # (n_rec,) int64, controller-grid sample at or before each instant
    sample_fraction: np.ndarray  # (n_rec,) [-] in [0, 1): the way to the next grid sample
    centres: np.ndarray  # (3,) the value each measured signal's error is formed about
    norms: np.ndarray  # (3,) [-] weighted squared norm of each measured signal about it


# ---------------------------------------------------------------- outputs
class MonitorOutputs(NamedTuple):
    """Preallocated (n,) arrays a Monitor run writes; row k as in the trace contract."""

    position: np.ndarray  # [rad]
    speed: np.ndarray  # [rad/s]
    current: np.ndarray  # [A] equivalent current, mean over the period ending at k T
    motor_angle: np.ndarray  # [rad]


class ReferenceOutputs(NamedTuple):
    """Preallocated (n,) arrays a Reference run writes."""

    position: np.ndarray  # [rad]
    speed: np.ndarray  # [rad/s]
    current: np.ndarray  # [A]
    current_a: np.ndarray  # [A]
    current_b: np.ndarray  # [A]
    current_c: np.ndarray  # [A]
    torque: np.ndarray  # [N m]
    motor_angle: np.ndarray  # [rad]
