"""docs/reference.md is the contract: every schema field, column, command and option is in it,
the README and docs link only inside the project, and the API example runs."""

from __future__ import annotations

import re
from pathlib import Path
from typing import get_args

import pytest
from pydantic import BaseModel

from .conftest import ROOT

REFERENCE = ROOT / "docs" / "reference.md"


def _models(annotation):
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        yield annotation
    for arg in get_args(annotation):
        yield from _models(arg)


def _fields(model: type[BaseModel], seen: set) -> set[str]:
    """Every field name of a schema and of the schemas nested in it."""
    if model in seen:
        return set()
    seen.add(model)
    names = set(model.model_fields)
    for field in model.model_fields.values():
        for nested in _models(field.annotation):
            names |= _fields(nested, seen)
    return names


def test_every_schema_field_is_documented():
    from emaprog.config.parameters import ParameterFile
    from emaprog.config.scenario import Campaign, History, Scenario

    text = REFERENCE.read_text()
    for model in (Scenario, Campaign, History, ParameterFile):
        missing = sorted(n for n in _fields(model, set()) if f"`{n}`" not in text)
        assert not missing, f"{model.__name__} fields missing from docs/reference.md: {missing}"


def test_every_trace_column_fault_quantity_and_report_key_is_documented():
    from emaprog.faults import CATALOGUE, QUANTITIES
    from emaprog.io.storage import COLUMNS

    text = REFERENCE.read_text()
    names = [
        *COLUMNS,
        *QUANTITIES,
        *(f.name for f in CATALOGUE),
        "estimate",
        "truth",
        "error",
        "health",
        "fitness",
        "evaluations",
        "elapsed_s",
        "seed",
        "settings",
        "emaprog_version",
        "environment",
        "inspection",
        "short_circuit_phase",
    ]
    assert not [n for n in names if f"`{n}`" not in text]


def test_every_command_and_option_is_documented():
    import typer.main

    from emaprog.cli import app

    text = REFERENCE.read_text()
    group = typer.main.get_command(app)
    assert set(group.commands) == {
        "check",
        "simulate",
        "convert",
        "identify",
        "calibrate",
        "commission",
        "sweep",
        "trend",
    }
    for name, command in group.commands.items():
        assert f"emaprog {name}" in text, name
        for param in command.params:
            for option in param.opts:
                if option.startswith("--") and option != "--help":
                    assert option in text, f"{name} {option}"


@pytest.mark.parametrize(
    "document", ["README.md", *(str(p.relative_to(ROOT)) for p in (ROOT / "docs").rglob("*.md"))]
)
def test_links_stay_inside_the_project(document):
    """Relative links resolve to files of the project; none leaves it (no ../shared)."""
    path = ROOT / document
    for target in re.findall(r"\]\(([^)#\s]+)", path.read_text()):
        if re.match(r"^[a-z]+://", target):
            continue
        resolved = (path.parent / target).resolve()
        assert resolved.is_relative_to(ROOT), f"{document} links outside the project: {target}"
        assert resolved.exists(), f"{document} links to a missing file: {target}"


def test_api_example_runs(monkeypatch):
    """The Python API example of the reference, as written (0.25 s Fig. 10 trace)."""
    block = REFERENCE.read_text().split("<!-- api-example -->", 1)[1]
    code = re.search(r"```python\n(.*?)```", block, re.S).group(1)
    monkeypatch.chdir(ROOT)
    exec(compile(code, "docs/reference.md", "exec"), {})


def _bash_commands(document: Path) -> list[str]:
    blocks = re.findall(r"```bash\n(.*?)```", document.read_text(), re.S)
    return [
        line.split("#")[0].strip()
        for block in blocks
        for line in block.splitlines()
        if line.strip().startswith("emaprog ")
    ]


def test_the_rig_tutorial_runs_the_readme_commands():
    """The rig tutorial's commands are the README's rig block (run as written by
    tests/test_rig_day.py), so the two cannot drift apart."""
    readme = (ROOT / "README.md").read_text().split("<!-- rig-commands -->", 1)[1]
    readme_commands = [
        line.strip()
        for line in readme.split("```bash", 1)[1].split("```", 1)[0].strip().splitlines()
    ]
    assert _bash_commands(ROOT / "docs" / "tutorials" / "rig-unit.md") == readme_commands


@pytest.mark.slow
def test_the_twin_tutorial_runs_as_written(tmp_path, monkeypatch):
    """Every command of the twin-experiment tutorial, as written, in a copy of the project's
    configs (exit 0 and the files it says); the quick campaign's sweep is left to
    tests/test_sweep.py (1.7 min on 2 cores)."""
    import shlex
    import shutil

    from typer.testing import CliRunner

    from emaprog.cli import app

    shutil.copytree(ROOT / "configs", tmp_path / "configs")
    monkeypatch.chdir(tmp_path)
    commands = _bash_commands(ROOT / "docs" / "tutorials" / "twin-experiment.md")
    assert any(c.startswith("emaprog identify") for c in commands)
    for command in commands:
        if command.startswith("emaprog sweep"):
            continue
        result = CliRunner().invoke(app, shlex.split(command)[1:])
        assert result.exit_code == 0, (command, result.output)
    assert (tmp_path / "out" / "fig10-report" / "report.json").exists()
    assert (tmp_path / "out" / "demo-trend" / "trend.json").exists()
