"""Rig recordings through a column map: units, formats, the built equivalent current, refusals,
and a Fig. 10 recording at 5 kHz (CSV and MATLAB, degrees, rpm, phase currents only)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import scipy.io
import yaml
from typer.testing import CliRunner

from emaprog.cli import app
from emaprog.errors import InputError
from emaprog.io.recordings import UNITS, load_column_map, read_recording

from .conftest import reference_run

#: Fig. 10's true faults (configs/fig10-multiple-faults.yaml) and the accuracy tolerances.
FIG10_TRUTH = {
    "friction": 1.8,
    "backlash": 4e-4,
    "short_circuit": {"a": 0.2, "b": 0.0, "c": 0.0},
    "zeta": 0.2,
}
RIG_MAP = {
    "time": {"column": "t_ms", "unit": "ms"},
    "command": {"column": "cmd_deg", "unit": "deg"},
    "position": {"column": "pos_deg", "unit": "deg"},
    "speed": {"column": "speed_rpm", "unit": "rpm"},
    "current_a": {"column": "ia_mA", "unit": "mA"},
    "current_b": {"column": "ib_A", "unit": "A"},
    "current_c": {"column": "ic_A", "unit": "A"},
}


def rig_columns(step: int = 2) -> dict[str, np.ndarray]:
    """The noisy Fig. 10 Reference trace as a logger writes it: every ``step``-th row
    (5 kHz for 2), ms, degrees, rpm, mA, phase currents only, a clock not starting at 0."""
    cols, _ = reference_run("fig10-multiple-faults", noise=True)
    deg = 180.0 / math.pi
    return {
        "t_ms": 1e3 * (cols["time"][::step] + 12.5),
        "cmd_deg": deg * cols["command"][::step],
        "pos_deg": deg * cols["position"][::step],
        "speed_rpm": 60.0 / (2.0 * math.pi) * cols["speed"][::step],
        "ia_mA": 1e3 * cols["current_a"][::step],
        "ib_A": cols["current_b"][::step],
        "ic_A": cols["current_c"][::step],
    }


def write_map(tmp_path, mapping=RIG_MAP, name="map.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(mapping, sort_keys=False))
    return path


def write_csv(tmp_path, columns, name="rig.csv", sep=","):
    path = tmp_path / name
    pd.DataFrame(columns).to_csv(path, index=False, sep=sep)
    return path


@pytest.mark.parametrize("kind,unit", [(k, u) for k, units in UNITS.items() for u in units])
def test_every_unit_converts_to_si(tmp_path, params, kind, unit):
    """Each unit's factor: a column written in that unit reads back in SI to 1e-12."""
    key = {
        "time": "time",
        "angle": "position",
        "speed": "speed",
        "current": "current",
        "torque": "torque",
    }[kind]
    n = 100
    si = {
        "time": np.arange(n) / 1e4,
        "command": np.zeros(n),
        "position": np.linspace(0, 0.1, n),
        "speed": np.linspace(-50, 50, n),
        "current": np.linspace(-3, 3, n),
        "torque": np.linspace(-1, 1, n),
    }
    factor = UNITS[kind][unit]
    raw = {name: values for name, values in si.items()}
    raw[key] = si[key] / factor
    mapping = {
        name: {
            "column": name,
            "unit": next(
                iter(
                    UNITS[
                        {
                            "time": "time",
                            "command": "angle",
                            "position": "angle",
                            "speed": "speed",
                            "current": "current",
                            "torque": "torque",
                        }[name]
                    ]
                )
            ),
        }
        for name in si
    }
    mapping[key]["unit"] = unit
    trace = read_recording(
        write_csv(tmp_path, raw), load_column_map(write_map(tmp_path, mapping)), params
    )
    assert np.allclose(trace[key], si[key], rtol=1e-12, atol=1e-15)
    if key != "time":
        assert np.allclose(trace["time"], si["time"], rtol=1e-12)


def test_csv_mat_struct_and_parquet_give_the_same_trace(tmp_path, params):
    """One recording in four containers (CSV with ',' and ';', MATLAB v5 top-level
    variables and struct, Parquet with the logger's names): the same SI trace, time from 0."""
    cols = rig_columns()
    column_map = load_column_map(write_map(tmp_path))
    reference = read_recording(write_csv(tmp_path, cols), column_map, params)
    scipy.io.savemat(tmp_path / "rig.mat", cols)
    scipy.io.savemat(tmp_path / "rig-struct.mat", {"rec": cols})
    pd.DataFrame(cols).to_parquet(tmp_path / "rig.parquet")
    struct_map = load_column_map(write_map(tmp_path, {**RIG_MAP, "variable": "rec"}, "s.yaml"))
    others = [
        read_recording(write_csv(tmp_path, cols, "semi.csv", ";"), column_map, params),
        read_recording(tmp_path / "rig.mat", column_map, params),
        read_recording(tmp_path / "rig-struct.mat", struct_map, params),
        read_recording(tmp_path / "rig.parquet", column_map, params),
    ]
    assert reference.time[0] == 0.0 and reference.metadata["time_offset"] == pytest.approx(
        12.5e-3 * 1e3
    )
    for other in others:
        for name in ("time", "command", "position", "speed", "current", "current_a"):
            assert np.allclose(other[name], reference[name], rtol=1e-12, atol=1e-12), name
    assert (
        reference.metadata["source"]["sha256"]
        and reference.metadata["column_map"]["speed"]["unit"] == "rpm"
    )


def test_equivalent_current_from_phase_currents(tmp_path, params):
    """(|Ia| + |Ib| + |Ic|)/2 signed like the torque. With the torque recorded the sign is
    exact; without it the replayed controller's current demand gives it: the wrong sign on
    less than 0.1 % of the current (measured 0.01 %: only around zero crossings)."""
    cols, _ = reference_run("fig10-multiple-faults", noise=True)
    raw = {
        "t": cols["time"],
        "cmd": cols["command"],
        "pos": cols["position"],
        "spd": cols["speed"],
        "ia": cols["current_a"],
        "ib": cols["current_b"],
        "ic": cols["current_c"],
        "tq": cols["torque"],
    }
    base = {
        "time": {"column": "t", "unit": "s"},
        "command": {"column": "cmd", "unit": "rad"},
        "position": {"column": "pos", "unit": "rad"},
        "speed": {"column": "spd", "unit": "rad/s"},
        **{f"current_{x}": {"column": f"i{x}", "unit": "A"} for x in "abc"},
    }
    path = write_csv(tmp_path, raw)
    magnitude = 0.5 * (
        np.abs(cols["current_a"]) + np.abs(cols["current_b"]) + np.abs(cols["current_c"])
    )
    with_torque = read_recording(
        path,
        load_column_map(
            write_map(tmp_path, {**base, "torque": {"column": "tq", "unit": "N m"}}, "t.yaml")
        ),
        params,
    )
    assert np.array_equal(with_torque["current"], magnitude * np.sign(cols["torque"]))
    replayed = read_recording(path, load_column_map(write_map(tmp_path, base)), params)
    wrong = np.sign(replayed["current"]) != np.sign(cols["torque"])
    assert np.sum(magnitude[wrong]) < 1e-3 * np.sum(magnitude)
    assert "replayed controller" in replayed.metadata["equivalent_current"]


def _bad_recordings(tmp_path):
    cols = rig_columns()
    n = cols["t_ms"].size

    def edited(**changes):
        out = {k: v.copy() for k, v in cols.items()}
        for key, fix in changes.items():
            fix(out[key])
        return out

    def nan_stretch(x):
        x[100:140] = np.nan

    def back(x):
        x[50], x[51] = x[51], x[50]

    def gap(x):
        x[300:] += 5.0

    duplicated = {k: np.insert(v, 10, v[10]) for k, v in cols.items()}
    slow = {k: v[::10] for k, v in cols.items()}  # 500 Hz
    return {
        "NaN stretch": (
            write_csv(tmp_path, edited(pos_deg=nan_stretch), "nan.csv"),
            RIG_MAP,
            "40 missing, NaN",
            "position.column",
        ),
        "duplicated rows": (
            write_csv(tmp_path, duplicated, "dup.csv"),
            RIG_MAP,
            "duplicated sample at row 11",
            "time",
        ),
        "time going back": (
            write_csv(tmp_path, edited(t_ms=back), "back.csv"),
            RIG_MAP,
            "goes back at row 51",
            "time",
        ),
        "gap": (write_csv(tmp_path, edited(t_ms=gap), "gap.csv"), RIG_MAP, "gap of", "time"),
        "missing column": (
            write_csv(tmp_path, {k: v for k, v in cols.items() if k != "speed_rpm"}, "nospeed.csv"),
            RIG_MAP,
            "no column 'speed_rpm'",
            "speed.column",
        ),
        "misspelt column": (
            write_csv(tmp_path, cols, "ok.csv"),
            {**RIG_MAP, "speed": {"column": "sped_rpm", "unit": "rpm"}},
            "did you mean 'speed_rpm'",
            "speed.column",
        ),
        "text column": (
            write_csv(tmp_path, {**cols, "pos_deg": np.array(["x"] * n)}, "text.csv"),
            RIG_MAP,
            "not one numeric value per row",
            "position.column",
        ),
        "unknown format": (
            write_csv(tmp_path, cols, "rig.xlsx"),
            RIG_MAP,
            "unknown recording format '.xlsx'",
            None,
        ),
        "below 1 kHz": (write_csv(tmp_path, slow, "slow.csv"), RIG_MAP, "at least 1000 Hz", "time"),
    }


def test_bad_recordings_exit_2_naming_file_and_key_and_write_nothing(tmp_path):
    runner = CliRunner()
    for case, (path, mapping, fragment, key) in _bad_recordings(tmp_path).items():
        map_path = write_map(tmp_path, mapping, f"{path.stem}.yaml")
        out = tmp_path / "out" / f"{path.stem}.parquet"
        command = (
            ["identify", str(path), "--columns", str(map_path), "-o", str(out.with_suffix(""))]
            if case == "below 1 kHz"
            else ["convert", str(path), "--columns", str(map_path), "-o", str(out)]
        )
        result = runner.invoke(app, command)
        assert result.exit_code == 2, (case, result.output)
        assert fragment in result.output and path.name in result.output, (case, result.output)
        assert key is None or key in result.output, (case, result.output)
        assert "Traceback" not in result.output
        assert not out.exists() and not out.with_suffix("").exists(), case


@pytest.mark.parametrize(
    "mapping,fragment",
    [
        (
            {**RIG_MAP, "sped": {"column": "x", "unit": "rpm"}},
            "unknown key 'sped'; did you mean 'speed'",
        ),
        (
            {**RIG_MAP, "speed": {"column": "speed_rpm", "unit": "rps"}},
            "unit 'rps' is not allowed for speed (allowed: rad/s, rpm, deg/s)",
        ),
        (
            {k: v for k, v in RIG_MAP.items() if k != "current_c"},
            "or all of current_a, current_b, current_c",
        ),
        ({k: v for k, v in RIG_MAP.items() if k != "time"}, "time"),
    ],
)
def test_bad_column_maps_are_refused_naming_the_key(tmp_path, mapping, fragment):
    path = write_map(tmp_path, mapping)
    with pytest.raises(InputError) as info:
        load_column_map(path)
    assert fragment in str(info.value) and "map.yaml" in str(info.value)


def test_matlab_v73_without_h5py_gets_a_clear_message(tmp_path, params):
    """A v7.3 file is HDF5; scipy cannot read it. Without h5py: say so and how to save it."""
    pytest.importorskip("scipy.io")
    try:
        import h5py  # noqa: F401

        pytest.skip("h5py is installed: v7.3 files are read through it")
    except ImportError:
        pass
    header = (
        b"MATLAB 7.3 MAT-file, Platform: GLNXA64".ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02IM"
    )
    path = tmp_path / "v73.mat"
    path.write_bytes(header + b"\x00" * 512)
    with pytest.raises(InputError, match="v7.3 .*h5py.*-v7"):
        read_recording(path, load_column_map(write_map(tmp_path)), params)


@pytest.mark.slow
@pytest.mark.parametrize("container", ["csv", "mat"])
def test_fig10_rig_recording_at_5_khz_is_identified_within_spec(tmp_path, container):
    """Fig. 10 as a rig logs it (5 kHz, degrees, rpm, mA and A, phase currents only, no
    emaprog metadata, clock starting at 12.5 s) identified through the column map: every
    quantity within tolerance of the truth (friction 5 % rel., backlash 5e-5 rad, PSC 0.03
    per phase on the right phase, zeta 0.05)."""
    cols = rig_columns(step=2)
    if container == "csv":
        path = write_csv(tmp_path, cols)
    else:
        path = tmp_path / "rig.mat"
        scipy.io.savemat(path, cols)
    import emaprog

    report = emaprog.identify(path, columns=write_map(tmp_path))
    est = report.estimate
    assert report.truth is None and report.data["trace"] == str(path)
    assert abs(est["friction"] / FIG10_TRUTH["friction"] - 1) <= 0.05, est
    assert abs(est["backlash"] - FIG10_TRUTH["backlash"]) <= 5e-5, est
    for x in "abc":
        assert abs(est["short_circuit"][x] - FIG10_TRUTH["short_circuit"][x]) <= 0.03, est
    assert report.data["short_circuit_phase"] == "a"
    assert abs(est["eccentricity"]["zeta"] - FIG10_TRUTH["zeta"]) <= 0.05, est


@pytest.mark.parametrize(
    "rate,shift", [(2e4, 2.5e-5), (5e3, 5e-5), (2e3, -2e-4), (1e4, 0.0), (3e3, 1e-4)]
)
def test_recorded_instants_stay_on_the_controller_grid(rate, shift):
    """Every recorded instant reads the Monitor between two existing grid samples (the
    kernel does not check bounds: an instant past the grid's end once read stray memory)."""
    from emaprog.models.common import recorded_instants

    grid = np.arange(5001) / 1e4
    t = 12.0 + np.arange(int(0.5 * rate) + 1) / rate
    instants = recorded_instants(t, grid, shift)
    assert instants.index.min() >= 0
    assert np.all(instants.index + (instants.fraction > 0) <= grid.size - 1)
    assert np.all((instants.fraction >= 0) & (instants.fraction < 1))
    inside = (t - t[0] + shift >= 0) & (t - t[0] + shift <= grid[-1])
    assert np.allclose(
        (instants.index + instants.fraction)[inside] / 1e4, (t - t[0] + shift)[inside], atol=1e-12
    )
    x = np.sin(grid * 40.0)
    assert np.allclose(
        instants.sample(x)[inside], np.sin((t - t[0] + shift)[inside] * 40.0), atol=1e-5
    )


def test_the_integrator_charge_is_the_offset_that_makes_the_demand_the_current():
    """A closed form: currents of magnitude ``|demand + c|`` plus 0.05 A of noise give back
    ``c`` (either sign, and 0 for a unit that starts empty) within 0.005 A (the noise over
    5001 samples moves a least-squares offset by about 1e-3 A); a long recording, whose
    coarse search reads thinned samples, gives the same."""
    from emaprog.io.recordings import integrator_charge

    rng = np.random.default_rng(3)
    time = np.arange(5001) / 1e4
    demand = 5.0 * np.sin(2.0 * np.pi * 3.0 * time)
    for charge in (0.8, -2.3, 0.0):
        magnitude = np.abs(demand + charge) + 0.05 * rng.standard_normal(time.size)
        assert abs(integrator_charge(demand, magnitude, 25.0) - charge) <= 0.005, charge
    long = integrator_charge(np.tile(demand, 30), np.tile(magnitude, 30), 25.0)
    assert abs(long) <= 0.005, long
