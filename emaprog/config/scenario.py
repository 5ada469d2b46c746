"""Scenario, identification and campaign files: pydantic v2 models (docs/reference.md, Scenario YAML and Campaign YAML).

Every model forbids unknown keys and non-finite numbers; every numeric field
states its unit and range. :func:`load_scenario` and :func:`load_campaign` turn
any problem into an :class:`~emaprog.errors.InputError` naming file and key.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    ValidationError,
    ValidationInfo,
    create_model,
    field_validator,
    model_serializer,
    model_validator,
)

from ..errors import from_validation_error
from ..faults import CATALOGUE, FAULT_NAMES, FAULTS, NUISANCE_NAMES, NUISANCES, Fault, Quantity
from ..kernels.structs import UNIT_COLUMNS
from .yamlfile import catalogue_fields, load_mapping

TWO_PI = 2.0 * math.pi
Name = Annotated[str, Field(pattern=r"^[A-Za-z0-9_-]{1,80}$", description="letters digits - _")]


def _num(
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    description: str = "",
) -> Any:
    """A strict float within bounds, for the models built from the catalogue at import
    (:func:`create_model`); the hand-written models spell their ``Annotated`` types out."""
    return Annotated[
        float,
        Field(
            strict=True,
            description=description,
            gt=lo if lo is not None and lo_open else None,
            ge=lo if lo is not None and not lo_open else None,
            lt=hi if hi is not None and hi_open else None,
            le=hi if hi is not None and not hi_open else None,
        ),
    ]


Angle = Annotated[
    float,
    Field(strict=True, ge=-0.4, le=0.4, description="[rad] surface angle, within the end stops"),
]
Frequency = Annotated[float, Field(strict=True, gt=0.0, le=200.0, description="[Hz]")]


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


# ------------------------------------------------------------------ commands
class StepCommand(Strict):
    kind: Literal["step"]
    amplitude: Angle
    time: Annotated[float, Field(strict=True, ge=0.0, le=60.0, description="[s] step instant")] = (
        0.0
    )
    offset: Angle = 0.0


class RampCommand(Strict):
    kind: Literal["ramp"]
    rate: Annotated[float, Field(strict=True, ge=-10.0, le=10.0, description="[rad/s]")]
    time: Annotated[float, Field(strict=True, ge=0.0, le=60.0, description="[s] ramp start")] = 0.0
    offset: Angle = 0.0


class SineCommand(Strict):
    kind: Literal["sine"]
    amplitude: Angle
    frequency: Frequency
    offset: Angle = 0.0


class ChirpCommand(Strict):
    kind: Literal["chirp"]
    amplitude: Angle
    start_frequency: Frequency
    end_frequency: Frequency
    offset: Angle = 0.0


class ConstantCommand(Strict):
    kind: Literal["constant"]
    offset: Angle = 0.0


Command = Annotated[
    StepCommand | RampCommand | SineCommand | ChirpCommand | ConstantCommand,
    Field(discriminator="kind"),
]
COMMAND_TAGS = ("step", "ramp", "sine", "chirp", "constant")


# ---------------------------------------------------------------------- load
class NoLoad(Strict):
    kind: Literal["none"]


class ConstantLoad(Strict):
    kind: Literal["constant"]
    torque: Annotated[
        float,
        Field(
            strict=True,
            ge=-5000.0,
            le=5000.0,
            description="[N m] hinge moment opposing +deflection",
        ),
    ]


class SpringLoad(Strict):
    kind: Literal["spring"]
    stiffness: Annotated[
        float, Field(strict=True, ge=0.0, le=1.0e5, description="[N m/rad] aerodynamic spring")
    ]
    torque: Annotated[
        float, Field(strict=True, ge=-5000.0, le=5000.0, description="[N m] constant part")
    ] = 0.0


Load = Annotated[NoLoad | ConstantLoad | SpringLoad, Field(discriminator="kind")]
LOAD_TAGS = ("none", "constant", "spring")


# -------------------------------------------------------------------- faults
def _quantity_field(q: Quantity):
    """The scenario field of one fault quantity: its range and unit from the catalogue."""
    return _num(q.lower, q.upper, hi_open=q.upper_open, description=f"[{q.unit}] {q.label}")


def _fault_value_type(fault: Fault) -> tuple[Any, Any]:
    """(annotation, healthy default) of a fault's value in ``faults:``."""
    if fault.layout == "scalar":
        (q,) = fault.quantities
        return _quantity_field(q), q.healthy
    fields: dict[str, Any] = {str(q.key): (_quantity_field(q), q.healthy) for q in fault.quantities}
    model = create_model(_camel(fault.name), __base__=Strict, __module__=__name__, **fields)
    FAULT_MODELS[model.__name__] = model
    return model, model()


#: The scenario models of the faults with more than one quantity, by class name, built from
#: the catalogue at import. They are this module's attributes through :func:`__getattr__`,
#: so that their instances pickle (sweep workers look a class up by module and name).
FAULT_MODELS: dict[str, type[Strict]] = {}


def __getattr__(name: str) -> type[Strict]:
    try:
        return FAULT_MODELS[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None


def _camel(name: str) -> str:
    return "".join(part.capitalize() for part in name.split("_"))


#: True faults of a scenario (docs/reference.md, Scenario YAML), one field per catalogue fault; omitted = healthy.
_FAULT_FIELDS: dict[str, Any] = {f.name: _fault_value_type(f) for f in CATALOGUE}
Faults = create_model("Faults", __base__=Strict, __module__=__name__, **_FAULT_FIELDS)


# ------------------------------------------------------------------ identify
FaultName = Literal[FAULT_NAMES]  # type: ignore[valid-type]  # the catalogue's names, at import


def _within(value: tuple[float, float], limits: tuple[float, float]) -> tuple[float, float]:
    """A search range ``(lo, hi)``: finite, ``lo < hi``, inside ``limits``."""
    lo, hi = value
    low, high = limits
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError("bounds must be finite numbers")
    if not lo < hi:
        raise ValueError(f"lower bound {lo} must be below upper bound {hi}")
    if lo < low or hi > high:
        raise ValueError(f"bounds must lie within [{low}, {high}]")
    return value


def _check_bounds(value: tuple[float, float], info: ValidationInfo):
    return _within(value, FAULTS[str(info.field_name)].bound_limits)


#: Search range of each fault's magnitudes (its angles span the circle).
Bounds = create_model(
    "Bounds",
    __base__=Strict,
    __module__=__name__,
    __validators__={"_check": field_validator(*FAULT_NAMES)(_check_bounds)},
    **catalogue_fields({f.name: (tuple[float, float], f.default_bounds) for f in CATALOGUE}),
)


class Signals(Strict):
    current: Annotated[
        float,
        Field(
            strict=True, ge=0.0, le=1e3, description="[-] weight of the equivalent-current error"
        ),
    ] = 1.0
    position: Annotated[
        float, Field(strict=True, ge=0.0, le=1e3, description="[-] weight of the position error")
    ] = 0.0
    speed: Annotated[
        float, Field(strict=True, ge=0.0, le=1e3, description="[-] weight of the speed error")
    ] = 0.0

    @model_validator(mode="after")
    def _some_weight(self):
        if self.current + self.position + self.speed <= 0:
            raise ValueError("at least one signal weight must be positive")
        return self


class GASettings(Strict):
    # omitted: 32 x 20 behind the least-squares polish (as accurate as 64 x 40 on the quick,
    # robustness and regression campaigns at a quarter of the Monitor runs), 64 x 40 for a
    # recording below 2.5 kHz or a unit in the form of a real actuator (a PWM drive or a
    # logger's chain) (emaprog.identification.run.ga_budget; docs/explanation/validation-and-speed.md)
    population: Annotated[int, Field(strict=True, ge=4, le=4096)] | None = Field(
        None,
        description=(
            "individuals per generation; omitted: 32, or 64 for a recording below 2.5 kHz"
            " or a unit with a PWM drive or a logger's chain"
        ),
    )
    generations: Annotated[int, Field(strict=True, ge=1, le=1000)] | None = Field(
        None,
        description=(
            "omitted: 20, or 40 for a recording below 2.5 kHz or a unit with a PWM drive"
            " or a logger's chain"
        ),
    )
    runs: Annotated[int, Field(strict=True, ge=1, le=16)] | None = Field(
        None,
        description=(
            "independent GA runs at most, each polished, the best fit kept, stopping once"
            " two reach the same best fit (within 0.1 %); omitted: 1, or 4 for a unit with a"
            " PWM drive or a logger's chain"
        ),
    )
    crossover: Annotated[
        float, Field(strict=True, ge=0.0, le=1.0, description="[-] crossover probability")
    ] = 0.7
    mutation: Annotated[
        float, Field(strict=True, ge=0.0, le=1.0, description="[-] mutation probability")
    ] = 0.2
    seed: Annotated[int, Field(strict=True, ge=0, le=2**32 - 1)] = 1
    strategy: Literal["numpy", "deap"] = Field(
        "numpy",
        description="numpy: generational GA, elitism, BLX-alpha crossover and decaying "
        "Gaussian mutation written in numpy; deap: DEAP's (mu + lambda) "
        "loop with selTournament, cxSimulatedBinaryBounded and "
        "mutPolynomialBounded",
    )

    @model_validator(mode="after")
    def _deap_probabilities(self):
        if self.strategy == "deap" and self.crossover + self.mutation > 1.0:
            raise ValueError(
                "with strategy deap, crossover + mutation must be at most 1 (each "
                "offspring is crossed, mutated or copied)"
            )
        return self

    @model_serializer(mode="wrap")
    def _without_unset_runs(self, handler: SerializerFunctionWrapHandler) -> dict:
        """``runs`` left out of a dump when unset: a campaign that does not name it keeps
        its hash (and its store resumes) from before the key existed."""
        data = handler(self)
        if self.runs is None:
            data.pop("runs", None)
        return data


NuisanceName = Literal[NUISANCE_NAMES]  # type: ignore[valid-type]  # the table's names


def _nuisance_bounds(value: tuple[float, float], info: ValidationInfo):
    return _within(value, NUISANCES[str(info.field_name)].limits)


#: Search range of each nuisance (``identify.nuisance_bounds``), from the nuisance table.
NuisanceBounds = create_model(
    "NuisanceBounds",
    __base__=Strict,
    __module__=__name__,
    __validators__=catalogue_fields({"_check": field_validator(*NUISANCES)(_nuisance_bounds)}),
    **catalogue_fields(
        {
            n.name: (
                tuple[float, float],
                Field(
                    n.bounds,
                    description=f"[{n.unit}] {n.description}, within [{n.limits[0]:g}, "
                    f"{n.limits[1]:g}]",
                ),
            )
            for n in NUISANCES.values()
        }
    ),
)


class IdentifySettings(Strict):
    estimate: list[FaultName] = Field(default_factory=lambda: list(FAULT_NAMES))
    bounds: Bounds = Bounds()
    signals: Signals = Signals()
    ga: GASettings = GASettings()
    refine: bool = True
    polish: Literal["powell", "least_squares"] = Field(
        "least_squares",
        description="local search after the GA (with refine): bounded Powell, or "
        "trust-region least squares on the residual with a batched "
        "Jacobian",
    )
    max_speed: (
        Annotated[
            float,
            Field(
                strict=True,
                gt=0.0,
                le=10000.0,
                description="[rad/s] motor speed above which samples are left "
                "out of the error; omitted: 40 % of the DC bus as "
                "pair back-EMF",
            ),
        ]
        | None
    ) = None
    nuisances: list[NuisanceName] | None = Field(
        None,
        description="operating conditions estimated beside the faults and reported under "
        "`nuisance`, never given a verdict; omitted: both for a real unit (a "
        "rig recording, or a commissioned unit's set), none for a twin "
        "experiment (emaprog.identification.defaults)",
    )
    nuisance_bounds: NuisanceBounds = NuisanceBounds()
    nominal_correction: Literal["reference", "recording", "none"] | None = Field(
        None,
        description="what is subtracted from the measured signals before fitting: "
        "the healthy Reference-Monitor difference with the set in use, "
        "the unit's commissioning recording's residual, or nothing "
        "(true/false: reference/none); omitted: chosen by the recording "
        "(emaprog.identification.defaults)",
    )

    @field_validator("nominal_correction", mode="before")
    @classmethod
    def _correction_flag(cls, value):
        if value is True:
            return "reference"
        return "none" if value is False else value

    @model_validator(mode="after")
    def _unique(self):
        if not self.estimate:
            raise ValueError("estimate must name at least one fault")
        if len(set(self.estimate)) != len(self.estimate):
            raise ValueError("estimate lists a fault twice")
        return self


# ------------------------------------------------------------------ scenario
class Scenario(Strict):
    name: Name
    description: str = ""
    parameters: str = Field("default", min_length=1, description="parameter set name or path")
    duration: Annotated[float, Field(strict=True, gt=0.0, le=60.0, description="[s]")]
    seed: Annotated[int, Field(strict=True, ge=0, le=2**32 - 1)] = 0
    command: Command
    load: Load = NoLoad(kind="none")
    faults: Faults = Faults()
    identify: IdentifySettings = IdentifySettings()

    @field_validator("command")
    @classmethod
    def _times_inside(cls, command, info: ValidationInfo):
        start = getattr(command, "time", None)
        duration = info.data.get("duration")
        if start is not None and duration is not None and start >= duration:
            raise ValueError(f"time {start} s must be before the end of the run ({duration} s)")
        return command


SCENARIO_TAGS = COMMAND_TAGS + LOAD_TAGS
#: Most healthy recordings a campaign case commissions its unit from (``commission: N``).
MAX_COMMISSION_RECORDINGS = 8


def _validate(model: type[BaseModel], data: dict, source: str | Path, tags=()) -> Any:
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise from_validation_error(source, exc, model, tags) from None


def parse_scenario(data: dict, source: str | Path) -> Scenario:
    return _validate(Scenario, data, source, SCENARIO_TAGS)


def load_scenario(path: str | Path) -> Scenario:
    """Load and validate a scenario file; checks its parameter set exists too."""
    from . import parameters

    path = Path(path)
    scenario = parse_scenario(load_mapping(path), path)
    parameters.load(scenario.parameters, relative_to=path.parent, source=path)
    return scenario


# ------------------------------------------------------------------ campaign
class Uniform(Strict):
    uniform: tuple[float, float]

    @model_validator(mode="after")
    def _ordered(self):
        lo, hi = self.uniform
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise ValueError("uniform bounds must be finite")
        if lo > hi:
            raise ValueError(f"uniform: lower {lo} above upper {hi}")
        return self


class PhaseDistribution(Strict):
    """A ``per_phase`` fault's distribution: which phase, and its fraction."""

    phase: Literal["any", "a", "b", "c"] = "any"
    fraction: Uniform

    @field_validator("fraction")
    @classmethod
    def _fraction_range(cls, dist):
        if dist.uniform[0] < 0 or dist.uniform[1] >= 1:
            raise ValueError("uniform range must lie within [0, 1)")
        return dist


class PolarDistribution(Strict):
    """A ``polar`` fault's distribution: its magnitude (zeta) and angle."""

    zeta: Uniform
    phase: Uniform = Uniform(uniform=(0.0, TWO_PI))

    @model_validator(mode="after")
    def _ranges(self):
        if self.zeta.uniform[0] < 0 or self.zeta.uniform[1] >= 1:
            raise ValueError("zeta: uniform range must lie within [0, 1)")
        if self.phase.uniform[0] < 0 or self.phase.uniform[1] > TWO_PI:
            raise ValueError("phase: uniform range must lie within [0, 2 pi]")
        return self


def _scalar_within_range(dist, info: ValidationInfo):
    (q,) = FAULTS[str(info.field_name)].quantities
    if dist is not None and (dist.uniform[0] < q.lower or dist.uniform[1] > q.upper):
        raise ValueError(f"uniform range must lie within [{q.lower}, {q.upper}]")
    return dist


DISTRIBUTION = {"scalar": Uniform, "per_phase": PhaseDistribution, "polar": PolarDistribution}
_SCALAR_FAULTS = [f.name for f in CATALOGUE if f.layout == "scalar"]

#: Distributions of the true faults of a campaign's cases, one optional field per fault.
FaultDistributions = create_model(
    "FaultDistributions",
    __base__=Strict,
    __module__=__name__,
    __validators__={"_scalar": field_validator(*_SCALAR_FAULTS)(_scalar_within_range)},
    **catalogue_fields(
        {
            "healthy_fraction": (_num(0.0, 1.0, description="[-] share of all-healthy cases"), 0.0),
            **{f.name: (DISTRIBUTION[f.layout] | None, None) for f in CATALOGUE},
        }
    ),
)


#: Parameters a campaign may spread from unit to unit (relative changes of the set's values).
SPREAD_PARAMETERS = tuple(name for name in UNIT_COLUMNS if name not in NUISANCES)


def _relative_range(dist, info: ValidationInfo):
    if dist is not None and (dist.uniform[0] < -0.5 or dist.uniform[1] > 1.0):
        raise ValueError("relative change: uniform range must lie within [-0.5, 1.0]")
    return dist


#: Per parameter, the distribution of each case's unit's relative change (+0.1 = 10 % more).
ActuatorSpread = create_model(
    "ActuatorSpread",
    __base__=Strict,
    __module__=__name__,
    __validators__={"_range": field_validator(*SPREAD_PARAMETERS)(_relative_range)},
    **catalogue_fields({name: (Uniform | None, None) for name in SPREAD_PARAMETERS}),
)


class Campaign(Strict):
    name: Name
    description: str = ""
    cases: Annotated[int, Field(strict=True, ge=1, le=1_000_000)]
    seed: Annotated[int, Field(strict=True, ge=0, le=2**32 - 1)] = 0
    scenario: str | Scenario = Field(description="base scenario: path or inline mapping")
    faults: FaultDistributions
    identify: IdentifySettings = IdentifySettings()
    actuator_spread: ActuatorSpread = Field(
        ActuatorSpread(), description="each case's unit: relative changes of the set's values"
    )
    hinge_moment: Uniform | None = Field(
        None, description="[N m] each case's constant hinge moment, unknown to the identification"
    )
    hinge_stiffness: Uniform | None = Field(
        None,
        description="[N m/rad] each case's aerodynamic spring, unknown to the identification "
        "(its commissioning recording draws its own)",
    )
    commission: bool | int = Field(
        False,
        description="each case first commissions its own unit from healthy recordings and "
        "identifies against it: true for one recording, or their number (1-8), each with "
        "its own noise seed, hinge moment and spring, as the rig workflow commissions from "
        "several",
    )

    @field_validator("commission")
    @classmethod
    def _commission_count(cls, value):
        if not isinstance(value, bool) and not 0 <= value <= MAX_COMMISSION_RECORDINGS:
            raise ValueError(
                f"true, false or a number of healthy recordings from 0 to "
                f"{MAX_COMMISSION_RECORDINGS}"
            )
        return value

    @property
    def commission_recordings(self) -> int:
        """How many healthy recordings each case's unit is commissioned from (0: none)."""
        return int(self.commission)

    @field_validator("hinge_moment")
    @classmethod
    def _hinge_range(cls, dist):
        if dist is not None and (dist.uniform[0] < -5000 or dist.uniform[1] > 5000):
            raise ValueError("uniform range must lie within [-5000, 5000] N m")
        return dist

    @field_validator("hinge_stiffness")
    @classmethod
    def _spring_range(cls, dist):
        if dist is not None and (dist.uniform[0] < 0 or dist.uniform[1] > 1.0e5):
            raise ValueError("uniform range must lie within [0, 1e5] N m/rad")
        return dist


def _base_scenario(scenario: str | Scenario, path: Path) -> Scenario:
    """A campaign's or history's base scenario: a path next to ``path``, or inline.

    Either way its parameter set must exist (checked now, not when cases run).
    """
    from . import parameters

    if isinstance(scenario, str):
        return load_scenario(path.parent / scenario)
    parameters.load(scenario.parameters, relative_to=path.parent, source=path)
    return scenario


def load_campaign(path: str | Path) -> tuple[Campaign, Scenario]:
    """Load a campaign and its base scenario (path resolved next to the campaign)."""
    path = Path(path)
    campaign = _validate(Campaign, load_mapping(path), path, SCENARIO_TAGS)
    return campaign, _base_scenario(campaign.scenario, path)


def load_any(path: str | Path) -> tuple[str, Any]:
    """Validate a scenario, campaign or history file (told apart by `cases`, `inspections`)."""
    data = load_mapping(path)
    if "cases" in data:
        return "campaign", load_campaign(path)
    if "inspections" in data:
        return "history", load_history(path)
    return "scenario", load_scenario(path)


# ------------------------------------------------------------------ history
class GrowthLaw(Strict):
    """Growth of a fault's severity with usage (see :mod:`emaprog.prognosis.fit`).

    linear: ``s(u) = initial + rate u``; exponential: ``s(u) = initial exp(rate u)``.
    The severity is the health-threshold scalar: ``k_f - 1`` for friction,
    the play [rad], the shorted fraction of the faulty phase, zeta.
    """

    law: Literal["linear", "exponential"]
    initial: Annotated[
        float, Field(strict=True, ge=0.0, le=5.0, description="severity at usage 0 [-] or [rad]")
    ]
    rate: Annotated[
        float,
        Field(strict=True, ge=0.0, le=1.0, description="[severity/h] linear, [1/h] exponential"),
    ]
    variability: Annotated[
        float,
        Field(
            strict=True,
            ge=0.0,
            le=2.0,
            description="[-] lognormal sigma of the rate, drawn once per history from its seed",
        ),
    ] = 0.0


class PhaseGrowth(GrowthLaw):
    """A ``per_phase`` fault grows on one phase."""

    phase: Literal["a", "b", "c"]


class PolarGrowth(GrowthLaw):
    """A ``polar`` fault grows in magnitude at a fixed angle."""

    angle: Annotated[
        float,
        Field(
            strict=True, ge=0.0, le=TWO_PI, description="[rad] angular position of the narrow gap"
        ),
    ] = 0.0


GROWTH = {"scalar": GrowthLaw, "per_phase": PhaseGrowth, "polar": PolarGrowth}


def _some_fault(self):
    if not any(getattr(self, f) is not None for f in FAULT_NAMES):
        raise ValueError("growth must give a law for at least one fault")
    return self


#: Growth law of each degrading fault of a synthetic history.
Growth = create_model(
    "Growth",
    __base__=Strict,
    __module__=__name__,
    __validators__=catalogue_fields({"_some_fault": model_validator(mode="after")(_some_fault)}),
    **catalogue_fields({f.name: (GROWTH[f.layout] | None, None) for f in CATALOGUE}),
)


class Inspections(Strict):
    start: Annotated[
        float, Field(strict=True, ge=0.0, le=1.0e6, description="[h] usage of the first inspection")
    ] = 0.0
    step: Annotated[
        float, Field(strict=True, gt=0.0, le=1.0e5, description="[h] usage between inspections")
    ]
    count: Annotated[int, Field(strict=True, ge=3, le=500)]


class History(Strict):
    """A synthetic degradation history (``emaprog trend --simulate``)."""

    name: Name
    description: str = ""
    actuator: Name = "actuator-1"
    seed: Annotated[int, Field(strict=True, ge=0, le=2**32 - 1)] = 0
    scenario: str | Scenario = Field(description="base scenario: path or inline mapping")
    inspections: Inspections
    growth: Growth
    identify: IdentifySettings = IdentifySettings()


def load_history(path: str | Path) -> tuple[History, Scenario]:
    """Load a synthetic history and its base scenario (path resolved next to the file)."""
    path = Path(path)
    history = _validate(History, load_mapping(path), path, SCENARIO_TAGS)
    return history, _base_scenario(history.scenario, path)
