"""The layering the code relies on: kernels reached only through the motor-model contract,
and kernel fault structs that follow the catalogue (docs/how-to/add-a-fault.md)."""

from __future__ import annotations

import ast

import pytest

from emaprog.faults import QUANTITIES, check_kernel_order
from emaprog.kernels.structs import FaultParams, MonitorFaults
from emaprog.models.family import MotorFamily, family_of

from .conftest import ROOT

PACKAGE = ROOT / "emaprog"
#: the data layer the kernels' structs are built from (parameter sets, scenarios, the
#: catalogue): below models/, so it may name the structs, never a kernel
STRUCT_USERS = ("config/", "faults.py")


def _imports(path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            base = "." * node.level + node.module
            yield base, [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, []


def test_no_module_above_models_imports_a_kernel():
    """Outside models/ and kernels/, no module imports emaprog.kernels (the structs only
    from the data layer): identification, commissioning, calibration and the recording
    reader go through :func:`emaprog.models.family.family_of`."""
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        rel = path.relative_to(PACKAGE).as_posix()
        if rel.startswith(("kernels/", "models/")):
            continue
        for module, names in _imports(path):
            if "kernels" not in module.split("."):
                continue
            structs_only = module.endswith("kernels.structs")
            if structs_only and rel.startswith(STRUCT_USERS):
                continue
            offenders.append(f"{rel}: {module} {names}")
    assert offenders == []


def test_the_bldc_family_satisfies_the_contract(params):
    family = family_of(params)
    assert isinstance(family, MotorFamily) and family.NAME == params.spec.motor.family == "bldc"


def test_kernel_fault_structs_follow_the_catalogue():
    """The shipped structs pass; a struct with a field out of the catalogue's order (or one
    fault more) is refused, naming it."""
    check_kernel_order(FaultParams._fields, MonitorFaults._fields)
    swapped = list(FaultParams._fields)
    swapped[0], swapped[1] = swapped[1], swapped[0]
    with pytest.raises(ImportError, match="FaultParams"):
        check_kernel_order(tuple(swapped), MonitorFaults._fields)
    with pytest.raises(ImportError, match="MonitorFaults"):
        check_kernel_order(FaultParams._fields, (*MonitorFaults._fields, "bearing_wear"))
    assert len(QUANTITIES) == len(FaultParams._fields)


def test_a_unit_file_without_a_faults_thresholds_still_loads(tmp_path):
    """A parameter set written before a fault was catalogued has no health thresholds for it:
    it loads, with the catalogue's defaults (the shipped set's), and nothing else moves."""
    import yaml

    from emaprog.config import parameters
    from emaprog.faults import FAULTS

    spec = yaml.safe_load((PACKAGE / "data" / "parameters" / "default.yaml").read_text())
    del spec["health"]["eccentricity"]
    path = tmp_path / "old-unit.yaml"
    path.write_text(yaml.safe_dump(spec))
    old = parameters.load(str(path))
    shipped = parameters.load("default")
    threshold = old.spec.health.eccentricity
    assert (threshold.incipient, threshold.degraded, threshold.failure) == FAULTS[
        "eccentricity"
    ].health
    assert old.spec.health == shipped.spec.health


def test_scenario_and_parameter_set_resolution(tmp_path):
    """Which set an identification uses, in one function (emaprog.api.resolve_sources):
    ``--parameters`` overrides; else the ``--scenario``'s, relative to the scenario file; else
    the set the trace was simulated with, found from any folder; else ``default``."""
    import shutil

    import yaml

    import emaprog
    from emaprog.api import resolve_sources

    unit = yaml.safe_load((PACKAGE / "data" / "parameters" / "default.yaml").read_text())
    unit["name"] = "unit-7"
    unit["mechanical"]["motor_inertia"] *= 1.05
    (tmp_path / "sets").mkdir()
    (tmp_path / "sets" / "unit-7.yaml").write_text(yaml.safe_dump(unit))
    scenario = yaml.safe_load((ROOT / "configs" / "chirp-nominal.yaml").read_text())
    scenario.update(parameters="sets/unit-7.yaml", duration=0.05)
    (tmp_path / "run.yaml").write_text(yaml.safe_dump(scenario))
    trace = tmp_path / "traces" / "run.parquet"
    trace.parent.mkdir()
    emaprog.simulate(tmp_path / "run.yaml", output=trace)
    moved = tmp_path / "elsewhere" / "run.parquet"
    moved.parent.mkdir()
    shutil.copy(trace, moved)

    assert resolve_sources(moved).params.spec.name == "unit-7"  # the trace's own set
    with_scenario = resolve_sources(moved, scenario=ROOT / "configs" / "chirp-nominal.yaml")
    assert with_scenario.params.spec.name == "default" and with_scenario.chosen is not None
    assert resolve_sources(moved, parameters="default").params.spec.name == "default"
    frame = emaprog.simulate(ROOT / "configs" / "chirp-nominal.yaml")
    assert resolve_sources(frame).params.spec.name == "default"
    assert resolve_sources(moved).embedded is not None


def test_no_module_writes_its_own_globals():
    """Module state has an owner: no ``globals()`` writes anywhere in the package (the
    scenario's fault models are a named table, found as module attributes through the
    module's ``__getattr__``), and a scenario holding them pickles as a sweep worker needs."""
    import pickle

    from emaprog.config import scenario
    from emaprog.config.scenario import load_scenario

    from .conftest import CONFIGS

    for path in (ROOT / "emaprog").rglob("*.py"):
        assert "globals()" not in path.read_text(), path
    fig10 = load_scenario(CONFIGS / "fig10-multiple-faults.yaml")
    assert pickle.loads(pickle.dumps(fig10)) == fig10
    assert scenario.ShortCircuit is scenario.FAULT_MODELS["ShortCircuit"]
    with pytest.raises(AttributeError):
        scenario.NotAFault  # noqa: B018
