"""A rig user's first day: the README's rig commands, run as written on the shipped example
rig files (logger CSV with free text, a units row, deg, rpm, mA, phase currents only), and
the same recordings as other loggers write them (no speed channel, a European export, a
pre-roll, two current channels swapped) and mis-mapped ones (exit 2 naming the channel).

The example unit is `default` moved by build tolerances (examples/rig/generate.py), its
inspections under 30 N m of hinge moment nobody tells emaprog. Tolerances are docs/reference.md's (Faults)
(docs/reference.md, Faults): friction 5 % relative, backlash 5e-5 rad, shorted fraction
0.03 on the right phase, zeta 0.05; the hinge moment must lie in its 90 % interval.
"""

from __future__ import annotations

import functools
import importlib.util
import json
import os
import re
import shlex
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from emaprog.cli import app
from emaprog.config import parameters as ps
from emaprog.io.recordings import check_plausible, load_column_map, read_recording

from .conftest import ROOT

RIG = ROOT / "examples" / "rig"
TRUTH = json.loads((RIG / "truth.json").read_text())["recordings"]
LOGGER_UNITS = {
    "Time_ms": "ms",
    "Cmd_deg": "deg",
    "Pos_deg": "deg",
    "MotSpd_rpm": "rpm",
    "Ia_mA": "mA",
    "Ib_mA": "mA",
    "Ic_mA": "mA",
    "MotAng_deg": "deg",
}
#: The example logger's columns (a motor angle only where a test adds one).
LOGGER_COLUMNS = list(LOGGER_UNITS)[:7]


def generator():
    spec = importlib.util.spec_from_file_location("rig_generate", RIG / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def readme_rig_commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    block = text.split("<!-- rig-commands -->", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    return [line.strip() for line in block.strip().splitlines() if line.strip()]


def run(args: list[str]):
    return CliRunner().invoke(app, args)


def within_spec(report: dict, truth: dict) -> list[str]:
    """Which quantities of a report are outside the tolerance of the truth."""
    est = report["estimate"]
    faults = truth["faults"]
    bad = []
    if abs(est["friction"] / faults.get("friction", 1.0) - 1.0) > 0.05:
        bad.append(f"friction {est['friction']:.3f}")
    if abs(est["backlash"] - faults.get("backlash", 0.0)) > 5e-5:
        bad.append(f"backlash {est['backlash']:.2e}")
    short = faults.get("short_circuit", {"a": 0.0, "b": 0.0, "c": 0.0})
    for phase in "abc":
        if abs(est["short_circuit"][phase] - short[phase]) > 0.03:
            bad.append(f"short {phase} {est['short_circuit'][phase]:.3f}")
    if est["eccentricity"]["zeta"] > 0.05:
        bad.append(f"zeta {est['eccentricity']['zeta']:.3f}")
    return bad


@pytest.fixture
def workdir(tmp_path):
    """A user's folder holding a copy of examples/rig (the commands write out/ there)."""
    shutil.copytree(RIG, tmp_path / "examples" / "rig")
    cwd = os.getcwd()
    os.chdir(tmp_path)
    yield tmp_path
    os.chdir(cwd)


@pytest.mark.slow
def test_readme_rig_commands_run_as_written_and_find_the_faults(workdir):
    """Every command of the README's rig section, exactly as written, exits 0; the
    inspections' estimates are within tolerance of the truth, the short circuit named on B
    when flagged, and the unknown 30 N m hinge moment within its 90 % interval."""
    commands = readme_rig_commands()
    assert len(commands) >= 3 and all(c.startswith("emaprog ") for c in commands)
    for command in commands:
        result = run(shlex.split(command)[1:])
        assert result.exit_code == 0, (command, result.output)
    reports = sorted(workdir.rglob("report.json"))
    assert len(reports) == 3
    for path in reports:
        report = json.loads(path.read_text())
        name = Path(report["trace"]).name
        truth = TRUTH[name]
        assert within_spec(report, truth) == [], (name, within_spec(report, truth))
        low, high = report["nuisance_interval"]["hinge_moment"]
        assert low <= truth["hinge_moment"] <= high, (name, low, high)
        assert set(report["health"].values()) <= {"nominal", "incipient", "degraded"}, name
        if truth["faults"].get("short_circuit"):
            assert report["health"]["short_circuit"] == "incipient"
            assert report["short_circuit_phase"] == "b" and report["phase_channels"]["b"] == "Ib_mA"
        else:
            assert report["short_circuit_phase"] is None
    trend = json.loads(next(workdir.rglob("trend.json")).read_text())
    assert trend["faults"]["friction"]["status"] in ("tracked", "failed")


# ------------------------------------------------------------ other loggers, same unit
def logger_frame(name: str) -> pd.DataFrame:
    return pd.read_csv(RIG / name, skiprows=[0, 1, 3])


def write_logger(
    frame: pd.DataFrame, path: Path, sep=",", decimal=".", preamble=(), units=True
) -> Path:
    lines = [*preamble, sep.join(frame.columns)]
    if units:
        lines.append(sep.join(LOGGER_UNITS[c] for c in frame.columns))
    body = frame.to_csv(sep=sep, decimal=decimal, index=False, header=False)
    path.write_text("\n".join(lines) + "\n" + body)
    return path


@functools.cache
def preroll_frames(seconds: float = 0.05) -> dict[str, pd.DataFrame]:
    """The example recordings with the logger started ``seconds`` before the command (the
    unit at rest under its hinge moment from the first sample), in the logger's format."""
    gen = generator()
    frames = {}
    for name in ("healthy-20Nm.csv", "healthy-40Nm.csv", "inspection-1500h.csv"):
        t = TRUTH[name]
        cols = gen.simulate_recording(
            t["hinge_moment"], t["faults"], t["noise_seed"], preroll=seconds
        )
        cols["time"] = cols["time"] + 12.0  # the logger's own clock
        rows = [r.split(",") for r in gen.logger_rows(cols)]
        frames[name] = pd.DataFrame(rows, columns=LOGGER_COLUMNS).astype(float)
    return frames


def variant(kind: str, name: str, folder: Path) -> Path:
    frame = preroll_frames()[name] if kind in ("preroll", "no-command") else logger_frame(name)
    if kind == "no-command":
        return write_logger(frame.drop(columns=["Cmd_deg"]), folder / name)
    if kind == "no-speed":
        return write_logger(frame.drop(columns=["MotSpd_rpm"]), folder / name)
    if kind == "european":
        return write_logger(
            frame,
            folder / name,
            sep=";",
            decimal=",",
            preamble=("Messdaten exportiert 01.12.2026 10:04", "Prüfstand 2; Kanal 1-7"),
        )
    if kind == "swapped":
        return write_logger(
            frame.rename(columns={"Ia_mA": "Ib_mA", "Ib_mA": "Ia_mA"})[frame.columns], folder / name
        )
    return write_logger(frame, folder / name, preamble=("pre-roll 50 ms",))


def column_map(folder: Path, drop=()) -> Path:
    mapping = {
        k: v for k, v in yaml.safe_load((RIG / "logger.yaml").read_text()).items() if k not in drop
    }
    path = folder / "map.yaml"
    path.write_text(yaml.safe_dump(mapping))
    return path


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["no-speed", "european", "preroll", "swapped", "no-command"])
def test_other_loggers_are_identified_with_the_documented_commands(tmp_path, kind):
    """The same unit through the README's commission and identify, recorded as other loggers
    write it. Swapping the Ia and Ib columns names the short on phase A, the channel now
    holding the shorted winding's current; the others name B. Without a command channel
    (and a 50 ms pre-roll) the test command comes from --scenario, placed by the response:
    its start within 0.2 ms (two samples) of the truth."""
    drop = {"no-speed": ("speed",), "no-command": ("command",)}.get(kind, ())
    mapping = column_map(tmp_path, drop=drop)
    test = ["--scenario", str(RIG / "test-command.yaml")] if kind == "no-command" else []
    healthy = [variant(kind, n, tmp_path) for n in ("healthy-20Nm.csv", "healthy-40Nm.csv")]
    inspection = variant(kind, "inspection-1500h.csv", tmp_path)
    unit = tmp_path / "unit.yaml"
    result = run(
        ["commission", *map(str, healthy), "--columns", str(mapping), "-o", str(unit), *test]
    )
    assert result.exit_code == 0, result.output
    result = run(
        [
            "identify",
            str(inspection),
            "--columns",
            str(mapping),
            "-p",
            str(unit),
            "-o",
            str(tmp_path / "report"),
            *test,
        ]
    )
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "report" / "report.json").read_text())
    truth = dict(TRUTH["inspection-1500h.csv"])
    if kind == "swapped":
        truth = {
            **truth,
            "faults": {**truth["faults"], "short_circuit": {"a": 0.12, "b": 0.0, "c": 0.0}},
        }
    assert within_spec(report, truth) == [], within_spec(report, truth)
    assert report["short_circuit_phase"] == ("a" if kind == "swapped" else "b")
    # swapped in the inspection only (commissioned from the swapped healthy files too): the
    # identity agrees with the commissioning's
    assert "agrees" in report["phase_identity"]["commissioning"]
    # the logger column that now holds the shorted winding's current
    assert report["phase_channels"][report["short_circuit_phase"]] == (
        "Ia_mA" if kind == "swapped" else "Ib_mA"
    )
    low, high = report["nuisance_interval"]["hinge_moment"]
    assert low <= 30.0 <= high
    if kind == "no-command":
        from emaprog.config import parameters
        from emaprog.config.scenario import load_scenario
        from emaprog.models.alignment import align_command

        params = parameters.load(str(unit))
        frame = pd.read_csv(inspection, skiprows=[1])
        found = align_command(
            load_scenario(RIG / "test-command.yaml"),
            params,
            frame["Time_ms"].to_numpy() * 1e-3,
            np.radians(frame["Pos_deg"].to_numpy()),
        )
        assert abs(found.delay - 0.05) < 2e-4 and found.delay_error < 2e-4, found


@pytest.mark.parametrize(
    "edit,channel,fragment",
    [
        ({"speed": {"column": "MotSpd_rpm", "unit": "rad/s"}}, "speed.unit", "says 'rpm'"),
        ({"position": {"column": "Pos_deg", "unit": "rad"}}, "position.unit", "says 'deg'"),
        ({"current_a": {"column": "Ia_mA", "unit": "A"}}, "current_a.unit", "says 'mA'"),
    ],
)
def test_a_map_whose_unit_contradicts_the_units_row_is_refused(tmp_path, edit, channel, fragment):
    """The logger's units row says rpm where the map says rad/s: exit 2 naming the channel,
    nothing written."""
    mapping = yaml.safe_load((RIG / "logger.yaml").read_text())
    mapping.update(edit)
    path = tmp_path / "map.yaml"
    path.write_text(yaml.safe_dump(mapping))
    out = tmp_path / "out"
    result = run(
        ["identify", str(RIG / "inspection-1500h.csv"), "--columns", str(path), "-o", str(out)]
    )
    assert result.exit_code == 2, result.output
    assert channel in result.output and fragment in result.output
    assert not out.exists()


def test_dialects_are_detected(tmp_path, params):
    """A European export (two free-text lines, units row, ';' and decimal comma), a tab file
    with comments and no units row, and the shipped file read to the same numbers."""
    from emaprog.io.recordings import load_column_map, read_recording

    frame = logger_frame("healthy-20Nm.csv")
    columns = load_column_map(RIG / "logger.yaml")
    plain = read_recording(RIG / "healthy-20Nm.csv", columns, params)
    european = read_recording(variant("european", "healthy-20Nm.csv", tmp_path), columns, params)
    tab = tmp_path / "tab.txt"
    tab.write_text("# logger DL-400\n# bench 2\n" + frame.to_csv(sep="\t", index=False))
    tabbed = read_recording(tab, columns, params)
    for other in (european, tabbed):
        for key in ("time", "command", "position", "speed", "current", "current_b"):
            assert np.array_equal(other[key], plain[key]), key
    layout = european.metadata["source"]["layout"]
    assert layout == {
        "delimiter": ";",
        "decimal": ",",
        "header_line": 3,
        "first_data_line": 5,
        "preamble_lines": 2,
        "units_lines": 1,
    }


def test_a_cut_last_line_is_refused_naming_it(tmp_path):
    """A file cut inside its last number, without a final newline (4431 mA read as 438
    otherwise): exit 2 naming the line; the complete file without a final newline reads."""
    text = (RIG / "healthy-20Nm.csv").read_text().rstrip("\n")
    cut = tmp_path / "cut.csv"
    cut.write_text(text[:-1])
    complete = tmp_path / "complete.csv"
    complete.write_text(text)
    result = run(
        [
            "convert",
            str(cut),
            "--columns",
            str(RIG / "logger.yaml"),
            "-o",
            str(tmp_path / "cut.parquet"),
        ]
    )
    assert result.exit_code == 2 and "last line" in result.output and "cut" in result.output
    assert re.search(r"line \d+", result.output)
    assert not (tmp_path / "cut.parquet").exists()
    result = run(
        [
            "convert",
            str(complete),
            "--columns",
            str(RIG / "logger.yaml"),
            "-o",
            str(tmp_path / "complete.parquet"),
        ]
    )
    assert result.exit_code == 0, result.output


def test_scale_offset_and_sign_calibrate_a_channel(tmp_path, params):
    """A current logged in volts through a 100 mV/A probe with a 0.02 V offset, and a
    position axis counted the other way, read back as the plain file's values to 1e-9."""
    from emaprog.io.recordings import load_column_map, read_recording

    frame = logger_frame("healthy-20Nm.csv")
    raw = frame.assign(Ia_V=frame["Ia_mA"] * 1e-4 + 0.02, Pos_deg=-frame["Pos_deg"])
    path = tmp_path / "volts.csv"
    raw.drop(columns=["Ia_mA"]).to_csv(path, index=False)
    mapping = yaml.safe_load((RIG / "logger.yaml").read_text())
    mapping["current_a"] = {"column": "Ia_V", "unit": "mA", "scale": 1e4, "offset": -200.0}
    mapping["position"] = {"column": "Pos_deg", "unit": "deg", "sign": -1}
    (tmp_path / "map.yaml").write_text(yaml.safe_dump(mapping))
    calibrated = read_recording(path, load_column_map(tmp_path / "map.yaml"), params)
    plain = read_recording(RIG / "healthy-20Nm.csv", load_column_map(RIG / "logger.yaml"), params)
    for key in ("position", "current_a", "current"):
        assert np.allclose(calibrated[key], plain[key], rtol=0, atol=1e-9), key


def test_phase_channels_are_balanced_by_the_series_law(tmp_path, params, monkeypatch):
    """A logger whose phase-current channels read 1.03, 0.97 and 1.00 times the current with
    offsets of 30, -25 and 10 mA (the unit's sensors ``current_gains``/``current_offsets``
    in the Reference): the reader finds each gain within 0.1 % (their standard errors are
    0.02 %) and each offset within 8 mA (about three standard errors of 2 mA) from the
    recording itself and corrects the channels, which brings the equivalent current to
    within a tenth of its uncorrected error from the same unit logged by right channels
    (measured 3.5 mA rms against 93 mA);
    the example logger's own channels, right, are left exactly as read (nothing beyond
    three standard errors), and a channel 30 % off the others (a scale mistake in the map)
    is not "balanced" away."""
    from emaprog.config.parameters import ParameterFile, derive
    from emaprog.io import recordings
    from emaprog.io.recordings import load_column_map, read_recording

    gen = generator()
    spec = gen.unit_parameters().spec.model_dump(mode="json")
    gains, offsets = [1.03, 0.97, 1.0], [0.03, -0.025, 0.01]
    spec["sensors"].update(current_gains=gains, current_offsets=offsets)
    logged = {}
    for name, unit in (
        ("off", derive(ParameterFile.model_validate(spec), "logger with channel errors")),
        ("right", gen.unit_parameters()),
    ):
        cols = gen.simulate_recording(20.0, {}, 11, unit=unit)
        logged[name] = pd.DataFrame(
            [r.split(",") for r in gen.logger_rows(cols)], columns=LOGGER_COLUMNS
        ).astype(float)
    columns = load_column_map(RIG / "logger.yaml")

    def read(frame, name):
        return read_recording(write_logger(frame, tmp_path / f"{name}.csv"), columns, params)

    trace = read(logged["off"], "off")
    found = trace.metadata["current_channels"]
    assert found["applied"], found
    scale = np.prod(gains) ** (1.0 / 3.0)  # the common scale is not in the currents
    for x, g, o in zip("abc", gains, offsets):
        assert found["estimate"]["gains"][x] == pytest.approx(g / scale, abs=1e-3), found
        assert found["offsets"][x] == pytest.approx(o, abs=8e-3), found
    right = read(logged["right"], "right")
    with monkeypatch.context() as m:
        m.setattr(recordings, "SIGNIFICANT", np.inf)
        uncorrected = read(logged["off"], "off")
    error = {
        name: float(np.sqrt(np.mean((t["current"] - right["current"]) ** 2)))
        for name, t in (("corrected", trace), ("uncorrected", uncorrected))
    }
    assert error["corrected"] < error["uncorrected"] / 10.0, error
    plain = read_recording(RIG / "healthy-20Nm.csv", columns, params)
    assert not plain.metadata["current_channels"]["applied"]
    raw = logger_frame("healthy-20Nm.csv")
    for k, name in (("current_a", "Ia_mA"), ("current_b", "Ib_mA"), ("current_c", "Ic_mA")):
        assert np.array_equal(plain[k], raw[name].to_numpy() * 1e-3), k
    mis = read(logged["right"].assign(Ia_mA=logged["right"]["Ia_mA"] * 1.3), "mis")
    assert not mis.metadata["current_channels"]["applied"]
    assert "scale or wiring" in mis.metadata["current_channels"]["note"]


def test_tdms_recording_reads_like_the_csv(tmp_path, params):
    """An NI TDMS file (npTDMS, the rig extra) with the logger's channels in one group and a
    waveform time track: the same trace as the CSV."""
    nptdms = pytest.importorskip("nptdms")
    from emaprog.io.recordings import load_column_map, read_recording

    frame = logger_frame("healthy-20Nm.csv")
    channels = [
        nptdms.ChannelObject(
            "rig",
            name,
            frame[name].to_numpy(),
            properties={"wf_increment": 1e-4, "wf_start_offset": 0.0},
        )
        for name in frame.columns
        if name != "Time_ms"
    ]
    path = tmp_path / "run.tdms"
    with nptdms.TdmsWriter(path) as writer:
        writer.write_segment([nptdms.GroupObject("rig"), *channels])
    mapping = yaml.safe_load((RIG / "logger.yaml").read_text())
    mapping["time"] = {"column": "waveform_time", "unit": "s"}
    mapping["speed"] = {"column": "rig/MotSpd_rpm", "unit": "rpm"}
    (tmp_path / "map.yaml").write_text(yaml.safe_dump(mapping))
    tdms = read_recording(path, load_column_map(tmp_path / "map.yaml"), params)
    plain = read_recording(RIG / "healthy-20Nm.csv", load_column_map(RIG / "logger.yaml"), params)
    for key in ("time", "position", "speed", "current"):
        assert np.allclose(tdms[key], plain[key], rtol=1e-12, atol=1e-9), key


def test_a_recording_that_starts_in_motion_is_refused(tmp_path):
    """Cut 0.1 s into the chirp: exit 2 saying it starts in motion, no report."""
    frame = logger_frame("inspection-1500h.csv").iloc[1000:]
    path = write_logger(frame, tmp_path / "late.csv")
    result = run(
        ["identify", str(path), "--columns", str(RIG / "logger.yaml"), "-o", str(tmp_path / "rep")]
    )
    assert result.exit_code == 2 and "starts in motion" in result.output, result.output
    assert not (tmp_path / "rep").exists()


@pytest.mark.parametrize(
    "edit,channel,fragment",
    [
        (
            {"speed": {"column": "MotSpd_rpm", "unit": "rpm", "sign": -1}},
            "speed",
            "sign is inverted",
        ),
        (
            {
                "speed": {
                    "column": "MotSpd_rpm",
                    "unit": "rpm",
                    "scale": 60 / (2 * 3.141592653589793),
                }
            },
            "speed",
            "rpm mapped as rad/s?",
        ),
        ({"position": {"column": "Pos_deg", "unit": "deg", "sign": -1}}, "position", "inverted"),
        (
            {"current_b": {"column": "Ib_mA", "unit": "mA", "scale": 1000.0}},
            "current",
            "mA mapped as A?",
        ),
    ],
)
def test_mis_mapped_channels_are_named_before_fitting(tmp_path, edit, channel, fragment):
    """A flipped sign or a wrong unit (here stated through scale/sign, as a units row would
    catch a plain unit): identify exits 2 before fitting, naming the channel and the
    evidence, nothing written. The
    shipped map passes (speed 0.98 x the position's derivative times the gear ratio)."""
    mapping = {**yaml.safe_load((RIG / "logger.yaml").read_text()), **edit}
    path = tmp_path / "map.yaml"
    path.write_text(yaml.safe_dump(mapping))
    result = run(
        [
            "identify",
            str(RIG / "inspection-1500h.csv"),
            "--columns",
            str(path),
            "-o",
            str(tmp_path / "rep"),
        ]
    )
    assert result.exit_code == 2, result.output
    assert channel in result.output and fragment in result.output, result.output
    assert not (tmp_path / "rep").exists()


@pytest.mark.parametrize(
    "scale,fragment",
    [(180.0 / np.pi, "deg mapped as rad?"), (-1.0, "the sign is inverted"), (0.5, "gear_ratio")],
)
def test_a_motor_angle_off_the_position_is_named_before_fitting(tmp_path, scale, fragment):
    """The Monitor commutates on a mapped motor angle, so its travel must be the position's
    times the gear ratio (within 30 %; a motor angle built as exactly that passes): a wrong
    unit, sign or scale exits 2 naming motor_angle and the likely mistake, nothing written."""
    frame = logger_frame("inspection-1500h.csv")
    frame["MotAng_deg"] = 180.0 * frame["Pos_deg"]
    path = write_logger(frame, tmp_path / "with-angle.csv")
    mapping = yaml.safe_load((RIG / "logger.yaml").read_text())
    good = {**mapping, "motor_angle": {"column": "MotAng_deg", "unit": "deg"}}
    bad = {**mapping, "motor_angle": {"column": "MotAng_deg", "unit": "deg", "scale": scale}}
    for name, content in (("good.yaml", good), ("bad.yaml", bad)):
        (tmp_path / name).write_text(yaml.safe_dump(content))
    unit = ps.load("default")
    good_map = load_column_map(tmp_path / "good.yaml")
    check_plausible(read_recording(path, good_map, unit, tmp_path / "good.yaml"), unit, path)
    result = run(
        ["identify", str(path), "--columns", str(tmp_path / "bad.yaml"), "-o", str(tmp_path / "r")]
    )
    assert result.exit_code == 2, result.output
    assert "motor_angle" in result.output and fragment in result.output, result.output
    assert not (tmp_path / "r").exists()


@pytest.mark.slow
def test_a_rewired_logger_is_said_against_the_commissioning(tmp_path):
    """Commissioned from the plain files, inspected with Ia and Ib swapped: the short is named
    on A (the channel carrying the shorted winding) and the report says the channel identity
    differs from the commissioning recordings'."""
    unit = tmp_path / "unit.yaml"
    healthy = [str(RIG / n) for n in ("healthy-20Nm.csv", "healthy-40Nm.csv")]
    assert (
        run(["commission", *healthy, "-c", str(RIG / "logger.yaml"), "-o", str(unit)]).exit_code
        == 0
    )
    inspection = variant("swapped", "inspection-1500h.csv", tmp_path)
    result = run(
        [
            "identify",
            str(inspection),
            "-c",
            str(RIG / "logger.yaml"),
            "-p",
            str(unit),
            "-o",
            str(tmp_path / "rep"),
        ]
    )
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "rep" / "report.json").read_text())
    assert report["short_circuit_phase"] == "a"
    assert "DIFFERS" in report["phase_identity"]["commissioning"]
    assert "Channel identity DIFFERS" in (tmp_path / "rep" / "report.md").read_text()


@pytest.mark.slow
def test_a_rotor_off_the_sensor_zero_is_located_and_its_short_named(tmp_path):
    """A unit whose rotor sits 69 degrees electrical off its angle sensors' zero, logged with
    a motor angle (docs/reference.md, "Phase identity"): the rotor's angle is found from the
    phase currents within 2 degrees (the estimator is within 0.7 on seven Reference
    recordings), the Fig. 10-like short on winding A is named on A within tolerance (assumed
    at electrical zero, it was read on C); with Ia and Ib then swapped in the inspection the
    commissioned sensor offset tells which pair was swapped: the short is named on the
    channel now carrying it (Ib) and the identity is said to differ."""
    import math

    gen = generator()
    unit_truth = gen.unit_parameters()
    faults = {"friction": 1.5, "short_circuit": {"a": 0.12, "b": 0.0, "c": 0.0}}
    frames = {}
    for name, hinge, fault, seed in (
        ("healthy-20Nm.csv", 20.0, {}, 31),
        ("healthy-40Nm.csv", 40.0, {}, 32),
        ("inspection.csv", 30.0, faults, 33),
    ):
        cols = gen.simulate_recording(
            hinge, fault, seed, unit=unit_truth, electrical_angle=math.radians(69.0)
        )
        frame = pd.DataFrame(
            [r.split(",") for r in gen.logger_rows(cols)], columns=LOGGER_COLUMNS
        ).astype(float)
        frame["MotAng_deg"] = np.round(np.degrees(cols["motor_angle"]), 4)
        frames[name] = write_logger(frame, tmp_path / name)
    mapping = yaml.safe_load((RIG / "logger.yaml").read_text())
    mapping["motor_angle"] = {"column": "MotAng_deg", "unit": "deg"}
    (tmp_path / "map.yaml").write_text(yaml.safe_dump(mapping))
    columns = str(tmp_path / "map.yaml")
    unit = tmp_path / "unit.yaml"
    result = run(
        [
            "commission",
            str(frames["healthy-20Nm.csv"]),
            str(frames["healthy-40Nm.csv"]),
            "-c",
            columns,
            "-o",
            str(unit),
        ]
    )
    assert result.exit_code == 0, result.output
    result = run(
        [
            "identify",
            str(frames["inspection.csv"]),
            "-c",
            columns,
            "-p",
            str(unit),
            "-o",
            str(tmp_path / "rep"),
        ]
    )
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "rep" / "report.json").read_text())
    truth = {"faults": faults}
    assert within_spec(report, truth) == [], within_spec(report, truth)
    assert report["short_circuit_phase"] == "a"
    assert abs(report["phase_identity"]["electrical_angle_deg"] - 69.0) < 2.0
    assert "agrees" in report["phase_identity"]["commissioning"]
    swapped = pd.read_csv(frames["inspection.csv"], skiprows=[1])
    swapped = swapped.rename(columns={"Ia_mA": "Ib_mA", "Ib_mA": "Ia_mA"})[swapped.columns]
    path = write_logger(swapped, tmp_path / "swapped.csv")
    result = run(
        ["identify", str(path), "-c", columns, "-p", str(unit), "-o", str(tmp_path / "sw")]
    )
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "sw" / "report.json").read_text())
    assert report["short_circuit_phase"] == "b" and report["phase_channels"]["b"] == "Ib_mA"
    assert "DIFFERS" in report["phase_identity"]["commissioning"]


def test_a_resolver_angle_logged_within_one_turn_is_unwrapped(tmp_path, params):
    """A single-turn resolver logs the motor angle within [0, 360) deg: it is made continuous
    before the speed is derived from it (an angle that wraps would make a speed spike of
    3.6e6 deg/s at every turn) and before the rotor's electrical angle is found; the
    provenance says how many turns were crossed."""
    import math

    from emaprog.io.recordings import load_column_map, read_recording

    gen = generator()
    cols = gen.simulate_recording(30.0, {}, 41, electrical_angle=math.radians(69.0))
    frame = pd.DataFrame(
        [r.split(",") for r in gen.logger_rows(cols)], columns=LOGGER_COLUMNS
    ).astype(float)
    frame["MotAng_deg"] = np.round(np.degrees(cols["motor_angle"]) % 360.0, 4)
    frame = frame.drop(columns=["MotSpd_rpm"])
    path = write_logger(frame, tmp_path / "resolver.csv")
    mapping = yaml.safe_load((RIG / "logger.yaml").read_text())
    del mapping["speed"]
    mapping["motor_angle"] = {"column": "MotAng_deg", "unit": "deg"}
    (tmp_path / "map.yaml").write_text(yaml.safe_dump(mapping))
    trace = read_recording(path, load_column_map(tmp_path / "map.yaml"), params)
    turns = int(np.ptp(cols["motor_angle"]) // (2 * math.pi))
    assert turns >= 1 and "turn boundaries" in trace.metadata["motor_angle"]
    error = np.asarray(trace["speed"]) - cols["speed"]
    # the derivative of a 1e-4 deg resolver over 1 ms against the Reference's own speed: the
    # 0.09-0.10 rad/s RMS measured with an unwrapped angle (docs/reference.md)
    assert float(np.sqrt(np.mean(error[10:-10] ** 2))) < 0.5
    assert abs(trace.metadata["phase_identity"]["electrical_angle_deg"] - 69.0) < 2.0


@pytest.mark.slow
def test_an_aerodynamic_spring_is_estimated_as_an_operating_condition(tmp_path):
    """The example unit inspected under 30 N m plus an aerodynamic spring of 2000 N m/rad,
    commissioned without one: with the default operating conditions the Monitor cannot
    explain the recording (measured 1161 x its floor: every fault inconclusive); with
    ``--nuisances hinge_moment,resistance_factor,hinge_stiffness`` the spring is estimated
    beside the faults (measured 2005 [1937, 2074] N m/rad, friction 1.487, short B 0.117)
    within tolerance, and the spring's interval holds the truth. The spring rate stated with
    ``--scenario`` (a load of kind spring) and the default operating conditions: the spring
    is applied, the hinge moment still estimated (measured: friction 1.482 [1.456, 1.508]
    against 1.487 [1.459, 1.514] with the spring estimated)."""
    gen = generator()
    faults = {"friction": 1.5, "short_circuit": {"a": 0.0, "b": 0.12, "c": 0.0}}
    cols = gen.simulate_recording(30.0, faults, 23, unit=gen.unit_parameters(), spring=2000.0)
    frame = pd.DataFrame(
        [r.split(",") for r in gen.logger_rows(cols)], columns=LOGGER_COLUMNS
    ).astype(float)
    inspection = write_logger(frame, tmp_path / "spring.csv")
    unit = tmp_path / "unit.yaml"
    healthy = [str(RIG / n) for n in ("healthy-20Nm.csv", "healthy-40Nm.csv")]
    assert (
        run(["commission", *healthy, "-c", str(RIG / "logger.yaml"), "-o", str(unit)]).exit_code
        == 0
    )
    common = [str(inspection), "-c", str(RIG / "logger.yaml"), "-p", str(unit)]
    result = run(["identify", *common, "-o", str(tmp_path / "plain")])
    assert result.exit_code == 0, result.output
    plain = json.loads((tmp_path / "plain" / "report.json").read_text())
    assert set(plain["health"].values()) == {"inconclusive"}
    nuisances = "hinge_moment,resistance_factor,hinge_stiffness"
    result = run(["identify", *common, "--nuisances", nuisances, "-o", str(tmp_path / "spring")])
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "spring" / "report.json").read_text())
    assert within_spec(report, {"faults": faults}) == [], within_spec(report, {"faults": faults})
    low, high = report["nuisance_interval"]["hinge_stiffness"]
    assert low <= 2000.0 <= high and abs(report["nuisance"]["hinge_stiffness"] / 2000.0 - 1) < 0.1
    low, high = report["nuisance_interval"]["hinge_moment"]
    assert low <= 30.0 <= high
    assert "aerodynamic spring" in (tmp_path / "spring" / "report.md").read_text()
    # a rig's programmed spring rate stated with --scenario: applied with the hinge moment
    # estimated (the constant part is unknown), the spring no longer fitted
    stated = yaml.safe_load((RIG / "test-command.yaml").read_text())
    stated["load"] = {"kind": "spring", "stiffness": 2000.0}
    scenario_file = tmp_path / "stated.yaml"
    scenario_file.write_text(yaml.safe_dump(stated))
    result = run(["identify", *common, "-s", str(scenario_file), "-o", str(tmp_path / "stated")])
    assert result.exit_code == 0, result.output
    known = json.loads((tmp_path / "stated" / "report.json").read_text())
    assert known["load"]["applied"]["stiffness"] == 2000.0
    assert "hinge_stiffness" not in known["nuisance"]
    assert within_spec(known, {"faults": faults}) == [], within_spec(known, {"faults": faults})
    low, high = known["nuisance_interval"]["hinge_moment"]
    assert low <= 30.0 <= high


def test_a_unit_commissioned_under_an_aerodynamic_spring_is_fitted_with_it(tmp_path):
    """The example unit's two healthy recordings under 20 and 40 N m plus a 2000 N m/rad
    aerodynamic spring. Commissioning finds the spring by default (screened at 662 +- 221,
    fitted 2017, 2016 N m/rad): k_e within 2 % of the truth (x0.990 for 0.98), the surface
    inertia within 3 % (x0.965 for 0.95), and the unit file records the springs. Holding the spring at 0
    (``--nuisances hinge_moment``) a spring reads as a negative inertia: the same recordings
    are accepted with the surface inertia x0.72 (x0.724 and x0.723 on two CPUs; asserted
    under x0.85), which is why it is fitted. Where else the held fit puts the mismatch moves
    with the last digits of the arithmetic (k_e x0.869 on one CPU, x0.964 on another), so it
    is not asserted."""
    gen = generator()
    truth = gen.unit_parameters().spec
    files = []
    for hinge, seed in ((20.0, 31), (40.0, 32)):
        cols = gen.simulate_recording(hinge, {}, seed, unit=gen.unit_parameters(), spring=2000.0)
        frame = pd.DataFrame(
            [r.split(",") for r in gen.logger_rows(cols)], columns=LOGGER_COLUMNS
        ).astype(float)
        files.append(str(write_logger(frame, tmp_path / f"healthy-{int(hinge)}.csv")))
    fitted = {}
    for label, extra in (("spring", []), ("held", ["--nuisances", "hinge_moment"])):
        unit = tmp_path / f"{label}.yaml"
        result = run(
            ["commission", *files, "-c", str(RIG / "logger.yaml"), "-o", str(unit), *extra]
        )
        assert result.exit_code == 0, result.output
        fitted[label] = yaml.safe_load(unit.read_text())
    spring = fitted["spring"]
    assert (
        abs(spring["electrical"]["back_emf_constant"] / truth.electrical.back_emf_constant - 1)
        < 0.02
    )
    assert (
        abs(spring["mechanical"]["surface_inertia"] / truth.mechanical.surface_inertia - 1) < 0.03
    )
    for entry in spring["commissioning"]["recordings"]:
        assert abs(entry["hinge_stiffness"] / 2000.0 - 1) < 0.03
        assert entry["hinge_stiffness_standard_error"] > 0
    held = fitted["held"]
    assert held["mechanical"]["surface_inertia"] / truth.mechanical.surface_inertia < 0.85
    assert "hinge_stiffness" not in held["commissioning"]["recordings"][0]


def test_commissioning_refuses_a_condition_it_does_not_fit_per_recording(tmp_path):
    """``commission --nuisances`` takes hinge_moment and hinge_stiffness; the winding
    resistance is a unit parameter commissioning fits itself: exit 2 naming the option, no
    unit written."""
    unit = tmp_path / "unit.yaml"
    result = run(
        [
            "commission",
            str(RIG / "healthy-20Nm.csv"),
            "-c",
            str(RIG / "logger.yaml"),
            "-o",
            str(unit),
            "--nuisances",
            "hinge_moment,resistance_factor",
        ]
    )
    assert result.exit_code == 2
    assert "--nuisances" in result.output and "resistance_factor" in result.output
    assert not unit.exists()
