"""Identification settings a recording leaves open, chosen for what the recording is.

A twin experiment (emaprog's own Reference Model run with exactly the parameter set in
use, its load known from the scenario it carries) and a real unit (a rig recording, or
any trace identified against a commissioned unit's set) need different defaults:

* ``identify.nuisances`` omitted: a real unit works under a hinge moment nobody wrote
  down and at a winding temperature of its own, so both ``hinge_moment`` and
  ``resistance_factor`` are estimated, and ``hinge_stiffness`` where the unit has met an
  aerodynamic spring (:func:`spring_met`); a twin's load is known and nothing is added
  (measured on the quick campaign: an extra gene costs the twins a little, see
  docs/reference.md "Identification defaults");
* ``identify.nominal_correction`` omitted: ``recording`` for a commissioned unit (the
  unit's own commissioning residual, when the inspection repeats that recording's
  command on its grid; else ``reference``, and the report says why), ``reference``
  otherwise.

:func:`resolve` returns settings in which both are concrete, and why, for the report.
"""

from __future__ import annotations

from typing import NamedTuple

from ..config.parameters import Parameters
from ..config.scenario import IdentifySettings

#: What a real unit estimates beside the faults when ``identify.nuisances`` is omitted.
REAL_UNIT_NUISANCES = ["hinge_moment", "resistance_factor"]
#: ... and the aerodynamic spring too where the unit has met one (:func:`spring_met`).
SPRING_NUISANCE = "hinge_stiffness"


def spring_met(params: Parameters) -> str | None:
    """Why a real unit's inspection estimates the aerodynamic spring by default, or None:
    its commissioning found a spring in a recording, or its set is of another form than the
    hysteresis drive with an ideal chain (the ``form`` basis, whose interval laws were
    calibrated with the spring estimated, on units under springs of 0-3000 N m/rad).

    Measured on an independently written actuator simulator (``benchmarks/independent_unit.py``,
    a healthy inspection under 30 N m and 2000 N m/rad, commissioned from ``default-pwm``):
    with the spring left out the fit was 3101 x its noise floor and the hinge moment read
    44.6 N m; with it, 149 x and 26.9 N m (before the integrator charge of
    :func:`~emaprog.io.recordings.integrator_charge`)."""
    record = params.spec.commissioning
    if record is not None and any(r.hinge_stiffness != 0.0 for r in record.recordings):
        return "its commissioning found an aerodynamic spring"
    if not params.hysteresis_form:
        return (
            "a unit of another form (its interval laws were calibrated with the spring estimated)"
        )
    return None


class Resolved(NamedTuple):
    settings: IdentifySettings  # nuisances and nominal_correction concrete
    real_unit: bool
    notes: dict[str, str]  # setting -> why it has its value


def is_real_unit(metadata: dict | None, params: Parameters) -> bool:
    """A rig recording (not written by emaprog's models), or a commissioned unit's set."""
    model = (metadata or {}).get("model")
    return model not in ("reference", "monitor") or params.spec.commissioning is not None


def resolve(
    settings: IdentifySettings,
    metadata: dict | None,
    params: Parameters,
    nuisances: list[str] | None = None,
    real_unit: bool | None = None,
    commissioned: bool | None = None,
) -> Resolved:
    """``settings`` with the open choices made (module docstring); ``nuisances`` (the
    command line's ``--nuisances``) overrides the settings' own; ``real_unit`` says what the
    trace is where its metadata cannot (a campaign's spread or commissioned unit), and
    ``commissioned`` whether ``params`` is a commissioned unit's set where the set cannot
    say so (a campaign's commissioned unit is a scaled set, not a commissioned file: it
    gets the rig workflow's ``recording`` all the same)."""
    real = is_real_unit(metadata, params) if real_unit is None else real_unit
    what = "a real unit" if real else "a twin experiment"
    notes = {}
    update: dict = {}
    if nuisances is not None:
        update["nuisances"] = list(nuisances)
        notes["nuisances"] = "--nuisances"
    elif settings.nuisances is None:
        update["nuisances"] = list(REAL_UNIT_NUISANCES) if real else []
        notes["nuisances"] = f"default for {what}"
        spring = spring_met(params) if real else None
        if spring is not None:
            update["nuisances"].append(SPRING_NUISANCE)
            notes["nuisances"] += f"; the aerodynamic spring too: {spring}"
    else:
        notes["nuisances"] = "identify.nuisances"
    if settings.nominal_correction is None:
        if commissioned is None:
            commissioned = params.spec.commissioning is not None
        update["nominal_correction"] = "recording" if commissioned else "reference"
        notes["nominal_correction"] = (
            "default for a commissioned unit" if commissioned else f"default for {what}"
        )
    else:
        notes["nominal_correction"] = "identify.nominal_correction"
    return Resolved(settings.model_copy(update=update), real, notes)
