"""Parameter sets: named YAML files -> validated, frozen structs for the kernels.

A parameter set holds physical values only (SI units). The numerical method
(time steps) lives in :mod:`emaprog.numerics`; operating inputs (command, load,
faults) live in the scenario. Derived constants are computed in one place,
:func:`derive`, and nothing mutates a built set.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path
from typing import Annotated, Literal, NamedTuple

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    create_model,
    field_validator,
    model_validator,
)

from ..errors import InputError, from_validation_error
from ..faults import CATALOGUE
from ..kernels.structs import (
    REGULATORS,
    ControllerParams,
    ElectricalParams,
    MechanicalParams,
    Plant,
    SensorParams,
)
from .yamlfile import catalogue_fields, load_mapping

Pos = Annotated[float, Field(strict=True, gt=0)]
NonNeg = Annotated[float, Field(strict=True, ge=0)]
Real = Annotated[float, Field(strict=True)]


#: The parameters that vary from unit to unit and commissioning fits (docs/reference.md,
#: Commissioning; :data:`emaprog.fitting.commission.UNKNOWNS` gives their bounds).
COMMISSIONED = (
    "motor_inertia",
    "surface_inertia",
    "motor_viscous",
    "dynamic_friction",
    "static_friction",
    "phase_resistance",
    "back_emf_constant",
    "phase_inductance",
    "transmission_stiffness",
)


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


class Electrical(_Section):
    """Three-phase trapezoidal BLDC motor and its drive."""

    dc_bus_voltage: Pos = Field(description="[V] H-bridge DC link")
    pole_pairs: Annotated[int, Field(strict=True, ge=1, le=32)] = Field(description="[-]")
    phase_resistance: Pos = Field(description="[ohm] per phase")
    phase_inductance: Pos = Field(description="[H] per phase")
    back_emf_constant: Pos = Field(description="[V s/rad] per phase, flat top, mechanical speed")
    current_limit: Pos = Field(description="[A] saturation of the current reference")
    hysteresis_band: Pos = Field(description="[A] half width of the hysteresis current regulator")


class CurrentLoop(_Section):
    """How the drive regulates the winding current (docs/reference.md, Parameter-set YAML):
    a hysteresis regulator (the paper's) or a PWM voltage inverter with a PI current loop,
    as the drive's datasheet states it."""

    regulator: Literal["hysteresis", "pwm"] = Field(
        "hysteresis",
        description="'hysteresis': bang-bang on the active pair's current within "
        "electrical.hysteresis_band; 'pwm': centre-aligned PWM of the pair's legs, "
        "complementary switches with dead time, PI current loop sampled once a period",
    )
    pwm_frequency: Pos = Field(20000.0, description="[Hz] switching (and current sampling) rate")
    dead_time: Annotated[float, Field(strict=True, ge=0, le=5e-6)] = Field(
        1.0e-6, description="[s] both switches of a leg off at each transition"
    )
    current_bandwidth: Pos = Field(
        1500.0,
        description="[Hz] the PI loop's crossover: gains 2 pi f (2 L) and 2 pi f (2 R) on "
        "the active pair (zero on the winding's pole)",
    )
    back_emf_feedforward: bool = Field(
        True, description="the pair's back-EMF 2 k_e w (measured speed) added to the voltage demand"
    )
    computation_delay: Annotated[int, Field(strict=True, ge=0, le=2)] = Field(
        1, description="[PWM periods] from the current sample to the duty it sets"
    )
    proportional_gain: Pos | None = Field(
        None,
        description="[V/A] the PI's proportional gain on the pair current as the drive is set; "
        "without it 2 pi current_bandwidth (2 L) of this set",
    )
    integral_gain: Pos | None = Field(
        None,
        description="[V/(A s)] the PI's integral gain as the drive is set; without it "
        "2 pi current_bandwidth (2 R) of this set",
    )
    feedforward_gain: NonNeg | None = Field(
        None,
        description="[V s/rad] the back-EMF feed-forward on the measured speed as the drive is "
        "set; without it 2 k_e of this set when back_emf_feedforward, else 0",
    )

    @model_validator(mode="after")
    def _dead_time_within_period(self):
        if self.dead_time * self.pwm_frequency >= 0.1:
            raise ValueError("dead_time must be under a tenth of the PWM period")
        if not self.back_emf_feedforward and self.feedforward_gain:
            raise ValueError("feedforward_gain is given but back_emf_feedforward is false")
        return self


#: The drive's gain keys: omitted from a set's provenance while unset (derived from the
#: bandwidth), so that sets and campaigns written before they existed keep their hashes.
GAIN_KEYS = ("proportional_gain", "integral_gain", "feedforward_gain")


class Mechanical(_Section):
    """2-DOF transmission: motor side, compliant geared link with backlash, surface."""

    motor_inertia: Pos = Field(description="[kg m^2]")
    motor_viscous: NonNeg = Field(description="[N m s/rad] at the motor")
    static_friction: Pos = Field(description="[N m] Borello breakaway torque at the motor")
    dynamic_friction: Pos = Field(description="[N m] Borello sliding torque at the motor")
    gear_ratio: Pos = Field(description="[-] motor angle / surface angle")
    surface_inertia: Pos = Field(description="[kg m^2]")
    surface_damping: NonNeg = Field(description="[N m s/rad] at the surface")
    transmission_stiffness: Pos = Field(description="[N m/rad] at the output")
    transmission_damping: NonNeg = Field(description="[N m s/rad] at the output")
    end_stop: Pos = Field(description="[rad] surface travel limit (symmetric)")
    end_stop_stiffness: Pos = Field(description="[N m/rad] contact stiffness of the stops")
    end_stop_damping: NonNeg = Field(description="[N m s/rad] contact damping of the stops")

    @model_validator(mode="after")
    def _static_above_dynamic(self):
        if self.static_friction < self.dynamic_friction:
            raise ValueError("static_friction must be >= dynamic_friction (Borello model)")
        return self


class Controller(_Section):
    """Digital position and speed loops (PI with anti-windup), ZOH at `rate`."""

    rate: Pos = Field(description="[Hz] controller sample rate = trace sample rate")
    position_gain: Pos = Field(description="[(rad/s motor)/rad surface] position loop P")
    position_integral: NonNeg = Field(description="[(rad/s motor)/(rad s)] position loop I")
    speed_gain: Pos = Field(description="[A s/rad] speed loop P")
    speed_integral: NonNeg = Field(description="[A/rad] speed loop I")
    speed_limit: Pos = Field(description="[rad/s] motor speed command saturation")


class AntiAlias(_Section):
    """A Butterworth low-pass on a signal line."""

    cutoff: Pos = Field(description="[Hz] -3 dB frequency")
    order: Annotated[int, Field(strict=True, ge=1, le=2)] = Field(2, description="[-] 1 or 2")


ChannelGain = Annotated[float, Field(strict=True, ge=0.8, le=1.2)]
ChannelOffset = Annotated[float, Field(strict=True, ge=-1.0, le=1.0)]


class Sensors(_Section):
    """Feedback transducers: offset, electrical noise (1 sigma), ADC."""

    position_offset: Real = Field(description="[rad] position transducer offset")
    position_noise: NonNeg = Field(description="[rad] 1-sigma noise on the position line")
    speed_noise: NonNeg = Field(description="[rad/s] 1-sigma noise on the speed line")
    current_noise: NonNeg = Field(description="[A] 1-sigma noise on each phase-current line")
    adc_bits: Annotated[int, Field(strict=True, ge=8, le=24)] = Field(description="[bit]")
    position_range: Pos = Field(description="[rad] ADC full scale (+/-)")
    speed_range: Pos = Field(description="[rad/s] ADC full scale (+/-)")
    current_range: Pos = Field(description="[A] ADC full scale (+/-)")
    position_filter: AntiAlias | None = Field(
        None, description="analog anti-alias filter on the position line (omitted: none)"
    )
    current_filter: AntiAlias | None = Field(
        None, description="analog anti-alias filter on each current line (omitted: none)"
    )
    speed_source: Literal["tachometer", "angle"] = Field(
        "tachometer",
        description="'tachometer': the motor speed on its own line; 'angle': the motor "
        "angle read by a resolver of angle_bits, differenced over the controller period",
    )
    speed_filter: AntiAlias | None = Field(
        None,
        description="the tachometer line's analog anti-alias filter, or with speed_source "
        "'angle' the digital filter on the differenced angle (omitted: none)",
    )
    angle_bits: Annotated[int, Field(strict=True, ge=8, le=24)] = Field(
        16, description="[bit] resolver resolution per motor revolution (speed_source angle)"
    )
    current_sampling: Literal["mean", "point"] = Field(
        "mean",
        description="'mean': each logged current is its mean over the controller period "
        "(integrate-and-dump); 'point': its value at the sample instant",
    )
    current_gains: tuple[ChannelGain, ChannelGain, ChannelGain] = Field(
        (1.0, 1.0, 1.0),
        description="[-] each phase-current channel's gain (a, b, c): the logger reads "
        "gain x current + offset",
    )
    current_offsets: tuple[ChannelOffset, ChannelOffset, ChannelOffset] = Field(
        (0.0, 0.0, 0.0), description="[A] each phase-current channel's offset (a, b, c)"
    )


#: The sensor chain's keys (docs/reference.md, Parameter-set YAML): omitted from a set's
#: provenance when they are at their defaults, so that sets and campaigns written before
#: the chain existed keep their hashes.
CHAIN_KEYS = (
    "position_filter",
    "current_filter",
    "speed_source",
    "speed_filter",
    "angle_bits",
    "current_sampling",
    "current_gains",
    "current_offsets",
)


class Motor(_Section):
    """Which motor family the set describes (docs/reference.md, Parameter-set YAML): its
    kernels, structs and tables (:mod:`emaprog.models.family`)."""

    family: Literal["bldc"] = Field(
        "bldc", description="motor family: bldc (six-step, trapezoidal back-EMF)"
    )


class Monitor(_Section):
    """Monitor Model equivalents; written by `emaprog calibrate`."""

    short_circuit_model: Literal["modulated", "averaged"] = Field(
        description="PSC law of the single-phase equivalent (docs/reference.md, The models)"
    )
    eccentricity_model: Literal["pair", "paper"] = Field(
        description="RE shape: 'pair' derived from the RM law, 'paper' = Eq. 5"
    )
    eccentricity_gain: Pos = Field(description="[-] c in Z = c * zeta")
    torque_gain_scale: Pos = Field(description="[-] nominal torque/back-EMF gain correction")
    commutation_loss: Annotated[float, Field(strict=True, ge=0, le=1e-3)] = Field(
        0.0, description="[s/rad] torque-per-ampere drop with motor speed (commutation dips)"
    )
    commutation_model: Literal["transient", "none"] = Field(
        "none",
        description="'transient': the outgoing phase freewheels after each sector "
        "change (its current in the equivalent current and the torque); "
        "'none': the pair current switches instantly",
    )


class Threshold(_Section):
    incipient: NonNeg = Field(description="severity from which the fault is reported")
    degraded: NonNeg = Field(description="severity from which maintenance should be planned")
    failure: NonNeg = Field(
        description="severity at which the actuator is to be replaced: "
        "the end of its remaining useful life (emaprog trend)"
    )

    @model_validator(mode="after")
    def _ordered(self):
        if not self.incipient < self.degraded <= self.failure:
            raise ValueError("thresholds must satisfy incipient < degraded <= failure")
        return self


#: Health verdict thresholds on the *severity* of each catalogue fault (its deviation from
#: healthy: :attr:`emaprog.faults.Fault.severity`).
Health = create_model(
    "Health",
    __base__=_Section,
    __module__=__name__,
    **catalogue_fields(
        {
            f.name: (
                Threshold,
                Field(
                    default_factory=lambda f=f: Threshold(
                        incipient=f.health[0], degraded=f.health[1], failure=f.health[2]
                    ),
                    description=f"{f.severity}; omitted: {f.health} (the catalogue's)",
                ),
            )
            for f in CATALOGUE
        }
    ),
)


class FittedValue(_Section):
    """One commissioned parameter: its value, the base set's, and the standard error [its unit]."""

    value: Pos
    base: Pos
    standard_error: NonNeg


class CommissioningRecording(_Section):
    """A healthy recording a unit was commissioned from."""

    file: str = Field(description="the recording (absolute path when it was a file)")
    sha256: str
    columns: str | None = Field(
        None,
        description="the column map it was read through (absolute path), null for a trace file",
    )
    hinge_moment: Real = Field(description="[N m] constant hinge moment during the recording")
    hinge_moment_standard_error: NonNeg = Field(description="[N m]")
    hinge_stiffness: Real = Field(
        0.0,
        description="[N m/rad] aerodynamic spring during the recording (fitted with "
        "--nuisances hinge_stiffness; else 0)",
    )
    hinge_stiffness_standard_error: NonNeg = Field(0.0, description="[N m/rad]")
    residual: dict[str, NonNeg] = Field(
        description="RMS of the fit residual per signal over the RMS of the signal [-] (1 ms mean)"
    )
    phase_identity: dict | None = Field(
        None,
        description="which logger channel carried which model winding (rig recordings "
        "with three phase currents; docs/reference.md, Rig recordings)",
    )


class Commissioning(_Section):
    """Where a commissioned unit's values come from (written by `emaprog commission`)."""

    date: str
    emaprog_version: str
    base: str = Field(description="the parameter set the unit was fitted from")
    recordings: list[CommissioningRecording]
    fitted: dict[str, FittedValue] = Field(description="parameters the recordings determined")
    not_determined: list[str] = Field(
        description="parameters held at the base value: the recordings do not determine them"
    )
    degenerate: list[str] = Field(
        description="combinations of parameters the recordings barely constrain, in words"
    )
    residual: NonNeg = Field(description="RMS of the whole normalised fit residual [-]")
    tolerances: dict[str, float] | None = Field(
        None, description="the base set's build tolerances the fit took as its prior (null: none)"
    )
    from_tolerance: list[str] = Field(
        default_factory=list,
        description="parameters with a tolerance that the recordings barely narrow: fitted, "
        "but their value is the tolerance's as much as the recordings'",
    )


class ParameterFile(_Section):
    name: Annotated[str, Field(pattern=r"^[A-Za-z0-9_-]+$")]
    description: str
    source: str = Field(description="where the values come from")
    changes: list[str] = Field(default_factory=list, description="record of tuning changes")
    motor: Motor = Field(default_factory=Motor, description="the motor family (omitted: bldc)")
    electrical: Electrical
    drive: CurrentLoop = Field(
        default_factory=CurrentLoop, description="the current regulator (omitted: hysteresis)"
    )
    mechanical: Mechanical
    controller: Controller
    sensors: Sensors
    monitor: Monitor
    health: Health
    commissioning: Commissioning | None = Field(
        None, description="a commissioned unit's provenance (emaprog commission)"
    )
    tolerances: dict[str, Annotated[float, Field(strict=True, gt=0.0, le=1.0)]] | None = Field(
        None,
        description="build tolerances (relative, +/-) of the parameters that vary from unit "
        "to unit, from the datasheets: commissioning's prior (docs/reference.md, "
        "Commissioning); omitted: none",
    )

    @field_validator("tolerances")
    @classmethod
    def _tolerance_names(cls, value):
        unknown = sorted(set(value or ()) - set(COMMISSIONED))
        if unknown:
            raise ValueError(
                f"no tolerance for {', '.join(unknown)}: commissioning fits "
                f"{', '.join(COMMISSIONED)}"
            )
        return value


# ---------------------------------------------------------------- kernel structs
class Parameters(NamedTuple):
    """A built parameter set: the validated file plus the kernel structs."""

    source_file: str
    spec: ParameterFile
    electrical: ElectricalParams
    mechanical: MechanicalParams
    controller: ControllerParams
    sensors: SensorParams

    def values(self) -> dict:
        """Plain values actually used (for provenance). A set of the first family without a
        ``motor`` section dumps as before, so that its campaigns keep their hashes."""
        values = self.spec.model_dump(mode="json")
        values["drive"] = _unset_gains(values["drive"])
        if values.get("tolerances") is None:  # sets without tolerances keep their hashes
            values.pop("tolerances", None)
        for key, default in (("motor", Motor()), ("drive", CurrentLoop())):
            if values.get(key) == _unset_gains(default.model_dump(mode="json")):
                del values[key]
        for key in CHAIN_KEYS:
            default = Sensors.model_fields[key].default
            if values["sensors"][key] == (list(default) if isinstance(default, tuple) else default):
                del values["sensors"][key]
        return values

    @property
    def hysteresis_form(self) -> bool:
        """Whether the unit has the hysteresis campaigns' form: a hysteresis regulator and an
        ideal sensor chain (no :data:`CHAIN_KEYS` away from their defaults). Its intervals'
        model-error laws are the ``unit`` basis'; any other form's are the ``form`` basis'
        (docs/reference.md, Confidence)."""
        sensors = self.values()["sensors"]
        return self.spec.drive.regulator == "hysteresis" and not any(
            k in sensors for k in CHAIN_KEYS
        )

    @property
    def plant(self) -> Plant:
        """The kernels' view of the unit: electrical, mechanical, controller, sensors."""
        return Plant(self.electrical, self.mechanical, self.controller, self.sensors)


def _unset_gains(section: dict) -> dict:
    """A dumped section without the drive's unset gain keys (:data:`GAIN_KEYS`)."""
    return {k: v for k, v in section.items() if not (k in GAIN_KEYS and v is None)}


def drive_gains(spec: ParameterFile) -> tuple[float, float, float]:
    """The PWM loop's (proportional [V/A], integral [V/(A s)], feed-forward [V s/rad]) gains:
    the drive section's own, else derived from its bandwidth and the set's winding."""
    e, loop = spec.electrical, spec.drive
    crossover = 2.0 * math.pi * loop.current_bandwidth
    return (
        loop.proportional_gain
        if loop.proportional_gain is not None
        else crossover * 2.0 * e.phase_inductance,
        loop.integral_gain
        if loop.integral_gain is not None
        else crossover * 2.0 * e.phase_resistance,
        loop.feedforward_gain
        if loop.feedforward_gain is not None
        else (2.0 * e.back_emf_constant if loop.back_emf_feedforward else 0.0),
    )


def fixed_drive_spec(params: Parameters) -> dict:
    """The set's file as a dict, a PWM drive's gains written out (:func:`drive_gains`), unset
    gain keys left out. A drive is tuned once, on the values of its set: a unit off the set
    (build tolerances, a commissioned unit, a warm winding) keeps the drive's gains, and
    does not retune it with its own inductance, resistance and back-EMF constant."""
    spec = params.spec.model_dump(mode="json")
    if params.spec.drive.regulator == "pwm":
        spec["drive"].update(zip(GAIN_KEYS, drive_gains(params.spec)))
    spec["drive"] = _unset_gains(spec["drive"])
    return spec


def _filter_fields(spec: AntiAlias | None) -> tuple[float, int]:
    """A filter's (cutoff [rad/s], order) in the kernels' form; (0, 1) for none."""
    return (0.0, 1) if spec is None else (2.0 * math.pi * spec.cutoff, spec.order)


def derive(spec: ParameterFile, source_file: str) -> Parameters:
    """Build kernel structs from a validated file; every derived value is here."""
    e, m, c, s = spec.electrical, spec.mechanical, spec.controller, spec.sensors
    levels = float(2**s.adc_bits)
    loop = spec.drive
    proportional, integral, feedforward = drive_gains(spec)
    return Parameters(
        source_file=source_file,
        spec=spec,
        electrical=ElectricalParams(
            e.dc_bus_voltage,
            float(e.pole_pairs),
            e.phase_resistance,
            e.phase_inductance,
            e.back_emf_constant,
            e.current_limit,
            e.hysteresis_band,
            REGULATORS.index(loop.regulator),
            1.0 / loop.pwm_frequency,
            loop.dead_time,
            proportional,
            integral,
            feedforward,
            loop.computation_delay,
        ),
        mechanical=MechanicalParams(**m.model_dump()),
        controller=ControllerParams(
            1.0 / c.rate,
            c.position_gain,
            c.position_integral,
            c.speed_gain,
            c.speed_integral,
            c.speed_limit,
            e.current_limit,
        ),
        sensors=SensorParams(
            s.position_offset,
            2 * s.position_range / levels,
            2 * s.speed_range / levels,
            2 * s.current_range / levels,
            s.position_range,
            s.speed_range,
            s.current_range,
            *_filter_fields(s.position_filter),
            *_filter_fields(s.speed_filter),
            *_filter_fields(s.current_filter),
            s.speed_source == "angle",
            2.0 * math.pi / 2**s.angle_bits,
            s.current_sampling == "point",
            *s.current_gains,
            *s.current_offsets,
        ),
    )


def builtin_dir() -> Path:
    """Folder of the parameter sets shipped with the package."""
    return Path(str(resources.files("emaprog") / "data" / "parameters"))


def builtin_names() -> list[str]:
    return sorted(p.stem for p in builtin_dir().glob("*.yaml"))


def resolve(
    name_or_path: str, relative_to: Path | None = None, source: str | Path = "parameters"
) -> Path:
    """Find a parameter set: a path ending in .yaml, else a shipped name.

    ``source`` is the file that named the set, for the error message.
    """
    candidate = Path(name_or_path)
    if candidate.suffix in (".yaml", ".yml"):
        if not candidate.is_absolute() and relative_to is not None:
            candidate = relative_to / candidate
        return candidate
    path = builtin_dir() / f"{name_or_path}.yaml"
    if path.is_file():
        return path
    raise InputError(
        source,
        f"unknown parameter set '{name_or_path}' (shipped: {', '.join(builtin_names())};"
        " or give a path ending in .yaml)",
        "parameters",
    )


def load(
    name_or_path: str = "default",
    relative_to: Path | None = None,
    source: str | Path = "parameters",
) -> Parameters:
    """Load, validate and derive a parameter set by name or path."""
    path = resolve(name_or_path, relative_to, source)
    data = load_mapping(path)
    try:
        spec = ParameterFile.model_validate(data)
    except ValidationError as exc:
        raise from_validation_error(path, exc, ParameterFile) from None
    return derive(spec, str(path.resolve()))


def scaled(params: Parameters, factors: dict[str, float], source: str) -> Parameters:
    """The set with some electrical or mechanical values multiplied by ``factors`` [-]
    (a unit off the set by build tolerances, a warm winding), its drive's gains kept
    (:func:`fixed_drive_spec`); checked like a file."""
    spec = fixed_drive_spec(params)
    for name, factor in factors.items():
        section = "electrical" if name in spec["electrical"] else "mechanical"
        spec[section][name] *= factor
    try:
        return derive(ParameterFile.model_validate(spec), source)
    except ValidationError as exc:
        raise from_validation_error(source, exc, ParameterFile) from None
