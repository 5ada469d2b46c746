"""Campaign sampling: the cases' faults, units and seeds, each from its own stream (docs/reference.md, Campaign YAML)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..config import parameters as parameter_sets
from ..config.parameters import Parameters
from ..config.scenario import SPREAD_PARAMETERS, Campaign, Faults, IdentifySettings, Scenario
from ..faults import (
    CATALOGUE,
    LAYOUTS,
    uniform_value,
)

SEED_LIMIT = 2**32  # scenario and GA seeds are uint32


class Commissioning(NamedTuple):
    """One of a case's healthy commissioning recordings: its noise seed, hinge moment and
    aerodynamic spring."""

    seed: int
    hinge_moment: float  # [N m]
    hinge_stiffness: float = 0.0  # [N m/rad]


class CaseSpec(NamedTuple):
    """Everything a worker needs to run one case; picklable, no open files."""

    case_id: int
    healthy: bool  # sampled as an all-healthy case (false-alarm check)
    scenario: Scenario  # base scenario with this case's faults and noise seed
    params: Parameters  # the set identification starts from (the shipped one)
    settings: IdentifySettings  # with this case's GA seed
    campaign_hash: str
    unit: Parameters | None = None  # the case's own unit (actuator_spread), None: params
    hinge_moment: float = 0.0  # [N m] unknown to the identification
    hinge_stiffness: float = 0.0  # [N m/rad] unknown to the identification
    #: commission the unit first from these healthy recordings (campaign ``commission``)
    commission: tuple[Commissioning, ...] | None = None


def identify_settings(campaign: Campaign, base: Scenario) -> IdentifySettings:
    """The campaign's ``identify:`` block when it has one, else the base scenario's."""
    return campaign.identify if "identify" in campaign.model_fields_set else base.identify


def sample_case(campaign: Campaign, case_id: int) -> tuple[bool, Faults, int, int]:
    """Draw case ``case_id``'s faults, Reference noise seed and GA seed.

    Every draw is made whether or not its distribution is given, in a fixed
    order (catalogue order), so adding a distribution to a campaign does not
    reshuffle the others' streams. Returns (healthy, faults, noise_seed, ga_seed).
    """
    rng = np.random.default_rng(np.random.SeedSequence(campaign.seed, spawn_key=(case_id,)))
    d = campaign.faults
    healthy = bool(rng.random() < d.healthy_fraction)  # type: ignore[attr-defined]  # built at import
    draws = {f.name: LAYOUTS[f.layout].draw(rng) for f in CATALOGUE}
    noise_seed, ga_seed = (int(s) for s in rng.integers(0, SEED_LIMIT, size=2))
    if healthy:
        return True, Faults(), noise_seed, ga_seed
    faults = Faults.model_validate(
        {f.name: LAYOUTS[f.layout].sampled(f, getattr(d, f.name), draws[f.name]) for f in CATALOGUE}
    )
    return False, faults, noise_seed, ga_seed


def sample_unit(
    campaign: Campaign, case_id: int
) -> tuple[dict[str, float], float, float, tuple[Commissioning, ...]]:
    """Case ``case_id``'s unit factors, hinge moment, aerodynamic spring and commissioning
    recordings (at least one, ``commission: N`` of them when N > 1).

    Drawn from the same stream as :func:`sample_case`, after all of its draws, every
    draw made whether or not its distribution is given: a campaign without spread keeps
    exactly the cases it had before these keys existed, and the second and later
    commissioning recordings are drawn after everything else, so that commissioning from
    more recordings keeps each case's unit, loads and first recording.
    """
    rng = np.random.default_rng(np.random.SeedSequence(campaign.seed, spawn_key=(case_id,)))
    rng.random()
    for fault in CATALOGUE:
        LAYOUTS[fault.layout].draw(rng)
    rng.integers(0, SEED_LIMIT, size=2)
    spread = {name: rng.random() for name in SPREAD_PARAMETERS}
    hinge_u, commission_hinge_u = rng.random(), rng.random()
    commission_seed = int(rng.integers(0, SEED_LIMIT))
    spring_u, commission_spring_u = rng.random(), rng.random()
    factors = {
        name: 1.0 + uniform_value(getattr(campaign.actuator_spread, name), u, 0.0)
        for name, u in spread.items()
    }
    hinge = uniform_value(campaign.hinge_moment, hinge_u, 0.0)
    recordings = [(commission_seed, commission_hinge_u, commission_spring_u)]
    for _ in range(1, campaign.commission_recordings):
        seed = int(rng.integers(0, SEED_LIMIT))
        recordings.append((seed, rng.random(), rng.random()))
    return (
        factors,
        hinge,
        uniform_value(campaign.hinge_stiffness, spring_u, 0.0),
        tuple(
            Commissioning(
                seed,
                uniform_value(campaign.hinge_moment, hinge_u, 0.0),
                uniform_value(campaign.hinge_stiffness, spring_u, 0.0),
            )
            for seed, hinge_u, spring_u in recordings
        ),
    )


def case_specs(
    campaign: Campaign,
    base: Scenario,
    params: Parameters,
    campaign_hash: str,
    case_ids: Iterable[int],
) -> Iterator[CaseSpec]:
    """The specs of the given cases (lazily: a large campaign is never all in memory)."""
    settings = identify_settings(campaign, base)
    for case_id in case_ids:
        healthy, faults, noise_seed, ga_seed = sample_case(campaign, case_id)
        spec = make_spec(
            case_id,
            healthy,
            f"{campaign.name}-case-{case_id}",
            base,
            faults,
            noise_seed,
            ga_seed,
            settings,
            params,
            campaign_hash,
        )
        factors, hinge, spring, commissioning = sample_unit(campaign, case_id)
        spread = {k: f for k, f in factors.items() if f != 1.0}
        unit = (
            parameter_sets.scaled(params, spread, f"{campaign.name}-case-{case_id} unit")
            if spread
            else None
        )
        yield spec._replace(
            unit=unit,
            hinge_moment=hinge,
            hinge_stiffness=spring,
            commission=commissioning if campaign.commission else None,
        )


def make_spec(
    case_id: int,
    healthy: bool,
    name: str,
    base: Scenario,
    faults: Faults,
    noise_seed: int,
    ga_seed: int,
    settings: IdentifySettings,
    params: Parameters,
    digest: str,
) -> CaseSpec:
    """One case: the base scenario with these faults and noise seed, the GA with its seed."""
    scenario = Scenario.model_validate(
        {
            **base.model_dump(mode="json"),
            "name": name,
            "seed": noise_seed,
            "faults": faults.model_dump(mode="json"),
            "identify": settings.model_dump(mode="json"),
        }
    )
    case_settings = IdentifySettings.model_validate(
        {
            **settings.model_dump(mode="json"),
            "ga": {**settings.ga.model_dump(mode="json"), "seed": ga_seed},
        }
    )
    return CaseSpec(case_id, healthy, scenario, params, case_settings, digest)


def with_hinge(scenario: Scenario, hinge_moment: float, hinge_stiffness: float = 0.0) -> Scenario:
    """The scenario with a constant hinge moment [N m] and an aerodynamic spring [N m/rad]
    added to its load."""
    if hinge_moment == 0.0 and hinge_stiffness == 0.0:
        return scenario
    load = scenario.load.model_dump(mode="json")
    if load["kind"] == "none":
        load = {"kind": "constant", "torque": 0.0}
    load["torque"] = load["torque"] + hinge_moment
    if hinge_stiffness != 0.0:
        load = {**load, "kind": "spring", "stiffness": load.get("stiffness", 0.0) + hinge_stiffness}
    return Scenario.model_validate({**scenario.model_dump(mode="json"), "load": load})


def load_parameters(campaign_path: Path, campaign, base: Scenario) -> Parameters:
    """The base scenario's parameter set, resolved next to the file that names it.

    ``campaign`` is a Campaign or a History: anything with a ``scenario`` that is
    a path (relative to ``campaign_path``) or an inline Scenario.
    """
    if isinstance(campaign.scenario, str):
        folder = (campaign_path.parent / campaign.scenario).parent
    else:
        folder = campaign_path.parent
    return parameter_sets.load(base.parameters, relative_to=folder, source=campaign_path)
