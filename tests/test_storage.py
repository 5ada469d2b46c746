"""Trace Parquet: round trip with units and provenance; every malformed file refused."""

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from emaprog.errors import InputError
from emaprog.io.storage import COLUMNS, Trace, column_units, read_trace, write_trace


def make_trace(n=50, metadata=None):
    t = np.arange(n) / 1e4
    cols = {
        "time": t,
        "command": np.sin(t),
        "position": np.cos(t),
        "speed": t * 2,
        "current": t * 3,
        "current_a": t,
        "current_b": -t,
        "current_c": t * 0,
        "torque": t,
        "motor_angle": t,
    }
    return Trace(cols, metadata)


def test_round_trip_keeps_values_units_and_provenance(tmp_path):
    meta = {"emaprog_version": "x", "model": "reference", "seed": 3}
    path = write_trace(tmp_path / "t.parquet", make_trace(metadata=meta))
    back = read_trace(path)
    for name, values in make_trace().columns.items():
        assert np.array_equal(back[name], values)
    assert back.metadata == meta
    assert column_units(path) == {name: COLUMNS[name][0] for name in make_trace().columns}
    assert not list(tmp_path.glob(".*tmp"))  # atomic write leaves no temporary file


def test_trace_without_metadata_is_valid(tmp_path):
    cols = make_trace().columns
    pq.write_table(
        pa.table({k: cols[k] for k in ("time", "command", "position", "speed", "current")}),
        tmp_path / "rig.parquet",
    )
    assert read_trace(tmp_path / "rig.parquet").metadata is None


def write_raw(path, columns, metadata=None):
    table = pa.table(columns)
    if metadata is not None:
        table = table.replace_schema_metadata({b"emaprog": metadata})
    pq.write_table(table, path)
    return path


def base_columns():
    cols = make_trace().columns
    return {k: cols[k] for k in ("time", "command", "position", "speed", "current")}


def with_nan():
    c = base_columns()
    c["current"] = c["current"].copy()
    c["current"][7] = np.nan
    return c


def non_monotonic():
    c = base_columns()
    c["time"] = c["time"].copy()
    c["time"][[3, 4]] = c["time"][[4, 3]]
    return c


BAD = {
    "missing column": (
        {k: v for k, v in base_columns().items() if k != "current"},
        None,
        "current",
    ),
    "NaN": (with_nan(), None, "NaN"),
    "non-monotonic time": (non_monotonic(), None, "increase"),
    "string column": ({**base_columns(), "speed": np.array(["x"] * 50)}, None, "speed"),
    "too short": ({k: v[:5] for k, v in base_columns().items()}, None, "at least 10"),
    "bad metadata": (base_columns(), b"{not json", "metadata"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_malformed_traces_are_refused_with_the_reason(tmp_path, case):
    columns, meta, fragment = BAD[case]
    path = write_raw(tmp_path / "bad.parquet", columns, meta)
    with pytest.raises(InputError) as info:
        read_trace(path)
    assert fragment in str(info.value) and "bad.parquet" in str(info.value)


def test_corrupt_and_missing_files(tmp_path):
    garbage = tmp_path / "garbage.parquet"
    garbage.write_bytes(b"\x00\x01PAR1 definitely not parquet" * 10)
    with pytest.raises(InputError, match="Parquet"):
        read_trace(garbage)
    with pytest.raises(InputError, match="not found"):
        read_trace(tmp_path / "absent.parquet")
    truncated = write_trace(tmp_path / "cut.parquet", make_trace())
    truncated.write_bytes(truncated.read_bytes()[:200])
    with pytest.raises(InputError):
        read_trace(truncated)
