"""Outputs refused before the work, nothing left behind, no silent overwrite; messages that
name what was meant (tagged-union typos, a logger file without --columns); `check` on
column maps and parameter sets; a trace's parameter set found from any folder."""

from __future__ import annotations

import os

import pytest
import yaml
from typer.testing import CliRunner

from emaprog.cli import app
from emaprog.config.scenario import parse_scenario
from emaprog.errors import InputError

from .conftest import CONFIGS, ROOT

RIG = ROOT / "examples" / "rig"


def run(args):
    return CliRunner().invoke(app, [str(a) for a in args])


def leftovers(folder):
    return [p for p in folder.rglob("*") if p.name.endswith(".tmp") or ".emaprog-probe-" in p.name]


@pytest.fixture(scope="module")
def trace(tmp_path_factory):
    path = tmp_path_factory.mktemp("trace") / "fig10.parquet"
    result = run(["simulate", CONFIGS / "fig10-multiple-faults.yaml", "-o", path])
    assert result.exit_code == 0, result.output
    return path


def test_outputs_that_cannot_be_written_are_refused_before_the_work(tmp_path, trace):
    """-o naming an existing folder (convert, simulate), an existing file (identify) or an
    unwritable place: exit 2 naming the output, in well under the work's time, no file."""
    (tmp_path / "dir").mkdir()
    cases = [
        ["convert", RIG / "healthy-20Nm.csv", "-c", RIG / "logger.yaml", "-o", tmp_path / "dir"],
        ["simulate", CONFIGS / "chirp-nominal.yaml", "-o", tmp_path / "dir"],
        ["identify", trace, "-o", trace],
        ["identify", trace, "-o", "/proc/emaprog-report"],
        ["commission", RIG / "healthy-20Nm.csv", "-c", RIG / "logger.yaml", "-o", tmp_path / "dir"],
    ]
    for args in cases:
        result = run(args)
        assert result.exit_code == 2, (args, result.output)
        assert "--output" in result.output and "Traceback" not in result.output, result.output
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["dir"]


def test_reports_and_units_are_not_overwritten_without_force(tmp_path, trace):
    out = tmp_path / "report"
    assert run(["identify", trace, "-o", out]).exit_code == 0
    stamp = (out / "report.json").stat().st_mtime_ns
    again = run(["identify", trace, "-o", out])
    assert again.exit_code == 2 and "--force" in again.output and "report.json" in again.output
    assert (out / "report.json").stat().st_mtime_ns == stamp
    assert run(["identify", trace, "-o", out, "--force"]).exit_code == 0
    unit = tmp_path / "unit.yaml"
    unit.write_text("name: mine\n")
    refused = run(["commission", RIG / "healthy-20Nm.csv", "-c", RIG / "logger.yaml", "-o", unit])
    assert refused.exit_code == 2 and "--force" in refused.output
    assert unit.read_text() == "name: mine\n" and not leftovers(tmp_path)


@pytest.mark.parametrize(
    "data,fragment",
    [
        (
            {
                "command": {
                    "kind": "chirp",
                    "amplitude": 0.05,
                    "start_freqency": 0.5,
                    "end_frequency": 10,
                }
            },
            "did you mean 'start_frequency'? (allowed here: amplitude, end_frequency, kind, offset, "
            "start_frequency)",
        ),
        (
            {
                "command": {"kind": "step", "amplitude": 0.05},
                "load": {"kind": "spring", "stifness": 10},
            },
            "did you mean 'stiffness'? (allowed here: kind, stiffness, torque)",
        ),
    ],
)
def test_a_typo_inside_a_tagged_union_lists_the_keys_of_its_kind(data, fragment):
    with pytest.raises(InputError) as caught:
        parse_scenario({"name": "x", "duration": 0.5, **data}, "s.yaml")
    assert fragment in str(caught.value)


def test_check_accepts_column_maps_and_parameter_sets(tmp_path):
    result = run(["check", RIG / "logger.yaml", CONFIGS / "parameters" / "default.yaml"])
    assert result.exit_code == 0, result.output
    assert (
        "column map of 7 channels" in result.output and "parameter set 'default'" in result.output
    )
    bad = tmp_path / "map.yaml"
    bad.write_text(
        yaml.safe_dump(
            {
                **yaml.safe_load((RIG / "logger.yaml").read_text()),
                "speed": {"column": "MotSpd_rpm", "unit": "rpms"},
            }
        )
    )
    refused = run(["check", bad])
    assert refused.exit_code == 2 and "speed" in refused.output and "rpm" in refused.output


def test_a_logger_file_without_columns_names_the_option():
    result = run(["identify", RIG / "inspection-1500h.csv", "-o", "/tmp/never-written"])
    assert result.exit_code == 2 and "--columns" in result.output


def test_a_trace_finds_its_parameter_set_from_another_folder(tmp_path, monkeypatch):
    """A scenario naming `unit.yaml` beside it, simulated in its folder, identified from
    elsewhere: the set is found through the trace's provenance (an absolute path)."""
    sim = tmp_path / "sim"
    sim.mkdir()
    (sim / "unit.yaml").write_text((CONFIGS / "parameters" / "default.yaml").read_text())
    scenario = yaml.safe_load((CONFIGS / "chirp-nominal.yaml").read_text())
    scenario.update(parameters="unit.yaml", duration=0.2)
    (sim / "s.yaml").write_text(yaml.safe_dump(scenario))
    monkeypatch.chdir(tmp_path)  # the trace goes to out/, which does not hold unit.yaml
    assert run(["simulate", os.path.join("sim", "s.yaml"), "-o", "out/t.parquet"]).exit_code == 0
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    result = run(["identify", os.path.join("..", "out", "t.parquet"), "-o", "rep"])
    assert result.exit_code == 0, result.output
