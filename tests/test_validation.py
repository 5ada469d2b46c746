"""Bad input: exit code 2, one message naming the file and the key path, never a traceback."""

from __future__ import annotations

import copy

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import yaml
from typer.testing import CliRunner

from emaprog.cli import app

from .conftest import CONFIGS, ROOT

runner = CliRunner()

GOOD = {
    "name": "ok",
    "duration": 0.2,
    "command": {"kind": "chirp", "amplitude": 0.05, "start_frequency": 0.5, "end_frequency": 10.0},
}


def mutate(path: list, value=None, delete: bool = False) -> dict:
    data = copy.deepcopy(GOOD)
    node = data
    for key in path[:-1]:
        node = node.setdefault(key, {})
    if delete:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return data


# (case, file text or mapping, fragments the message must hold)
CASES = [
    ("misspelt top key", mutate(["fualts"], {}), ["fualts", "did you mean 'faults'"]),
    ("unknown nested key", mutate(["command", "amplitud"], 0.1), ["command.amplitud"]),
    ("misspelt fault", mutate(["faults", "frction"], 2.0), ["faults.frction", "friction"]),
    ("wrong type", mutate(["duration"], "long"), ["duration"]),
    ("NaN", ".nan", ["duration", "finite"]),
    ("infinity", mutate(["faults", "friction"], float("inf")), ["faults.friction"]),
    ("negative duration", mutate(["duration"], -1.0), ["duration"]),
    ("friction out of range", mutate(["faults", "friction"], 50.0), ["faults.friction"]),
    (
        "shorted fraction >= 1",
        mutate(["faults", "short_circuit", "a"], 1.0),
        ["faults.short_circuit.a"],
    ),
    (
        "eccentricity out of range",
        mutate(["faults", "eccentricity", "zeta"], 1.5),
        ["faults.eccentricity.zeta"],
    ),
    (
        "chirp without end frequency",
        mutate(["command", "end_frequency"], delete=True),
        ["command", "end_frequency"],
    ),
    ("unknown command kind", mutate(["command", "kind"], "square"), ["command", "square"]),
    ("unknown load kind", mutate(["load"], {"kind": "gust"}), ["load"]),
    (
        "bounds reversed",
        mutate(["identify", "bounds", "friction"], [3.0, 1.0]),
        ["identify.bounds.friction", "below"],
    ),
    (
        "bounds outside limits",
        mutate(["identify", "bounds", "backlash"], [0.0, 1.0]),
        ["identify.bounds.backlash"],
    ),
    (
        "unknown fault to estimate",
        mutate(["identify", "estimate"], ["friction", "wear"]),
        ["identify.estimate"],
    ),
    ("all weights zero", mutate(["identify", "signals"], {"current": 0.0}), ["identify.signals"]),
    (
        "population too small",
        mutate(["identify", "ga", "population"], 2),
        ["identify.ga.population"],
    ),
    ("unsafe name", mutate(["name"], "../etc"), ["name"]),
    ("unknown parameter set", mutate(["parameters"], "nonexistent"), ["parameters", "default"]),
    ("missing required key", mutate(["command"], delete=True), ["command"]),
    ("list instead of mapping", "- a\n- b\n", ["mapping"]),
    ("YAML syntax error", "name: [unclosed\n", ["line"]),
    ("duplicate key", "name: a\nname: b\n", ["name"]),
    ("empty file", "", ["empty"]),
    ("binary garbage", b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe", []),
]


@pytest.mark.parametrize("case,content,fragments", CASES, ids=[c[0] for c in CASES])
def test_bad_scenario_exits_2_naming_file_and_key(tmp_path, case, content, fragments):
    path = tmp_path / "bad.yaml"
    if isinstance(content, dict):
        path.write_text(yaml.safe_dump(content))
    elif isinstance(content, bytes):
        path.write_bytes(content)
    elif content == ".nan":
        path.write_text(yaml.safe_dump(GOOD).replace("duration: 0.2", "duration: .nan"))
    else:
        path.write_text(content)
    result = runner.invoke(app, ["check", str(path)])
    assert result.exit_code == 2, result.output
    message = result.stderr if hasattr(result, "stderr") else result.output
    assert "Traceback" not in result.output and "Traceback" not in message
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message, message
    assert len(message.strip().splitlines()) == 1


def test_good_scenario_passes(tmp_path):
    path = tmp_path / "good.yaml"
    path.write_text(yaml.safe_dump(GOOD))
    result = runner.invoke(app, ["check", str(path)])
    assert result.exit_code == 0 and "ok" in result.output


def test_shipped_configs_and_campaigns_are_valid():
    files = sorted(CONFIGS.glob("*.yaml")) + sorted((ROOT / "campaigns").glob("*.yaml"))
    result = runner.invoke(app, ["check", *map(str, files)])
    assert result.exit_code == 0, result.output
    assert result.output.count("ok ") == len(files)


def test_campaign_errors_name_the_key(tmp_path):
    path = tmp_path / "camp.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "name": "c",
                "cases": 5,
                "scenario": str(CONFIGS / "chirp-nominal.yaml"),
                "faults": {"healthy_fraction": 1.5},
            }
        )
    )
    result = runner.invoke(app, ["check", str(path)])
    assert result.exit_code == 2 and "faults.healthy_fraction" in result.output


def test_identify_refuses_missing_corrupt_and_foreign_traces(tmp_path):
    missing = runner.invoke(
        app, ["identify", str(tmp_path / "none.parquet"), "-o", str(tmp_path / "r")]
    )
    assert missing.exit_code == 2 and "not found" in missing.output
    corrupt = tmp_path / "corrupt.parquet"
    corrupt.write_bytes(b"PAR1" + b"\x00" * 64)
    result = runner.invoke(app, ["identify", str(corrupt), "-o", str(tmp_path / "r")])
    assert result.exit_code == 2 and "corrupt.parquet" in result.output
    foreign = tmp_path / "foreign.parquet"
    pq.write_table(pa.table({"t": np.arange(20.0), "v": np.zeros(20)}), foreign)
    result = runner.invoke(app, ["identify", str(foreign), "-o", str(tmp_path / "r")])
    assert result.exit_code == 2 and "missing column" in result.output
    assert not (tmp_path / "r" / "report.json").exists()


def test_unknown_model_is_refused():
    result = runner.invoke(app, ["simulate", str(CONFIGS / "friction.yaml"), "--model", "magic"])
    assert result.exit_code == 2 and "--model" in result.output


def test_every_command_help_ends_with_an_example():
    for command in ("check", "simulate", "identify", "calibrate", "sweep", "trend"):
        result = runner.invoke(app, [command, "--help"])
        assert result.exit_code == 0 and "Example: emaprog " + command in result.output
