"""Degradation histories: one actuator's identification results over its usage.

Three sources, one shape (:class:`HistoryTable`):

* a Parquet table, one row per inspection, sorted by usage: ``actuator``
  (text), ``usage`` [h], and the estimated ``friction``, ``backlash``,
  ``short_circuit_a``, ``short_circuit_b``, ``short_circuit_c``,
  ``eccentricity_zeta`` (the catalogue's quantity names);
* a folder of ``report.json`` files written by
  ``emaprog identify TRACE --actuator ID --usage HOURS`` (searched recursively);
* a synthetic history YAML (:class:`~emaprog.config.scenario.History`): the growth
  laws are applied to the base scenario, each inspection is simulated on the
  Reference Model and identified with the GA through the sweep's execution and
  storage (``RESULTS_DIR/inspections/``, resumable).
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ..campaign import cases as campaigns
from ..config.parameters import Parameters
from ..config.scenario import Faults, History, Scenario
from ..errors import InputError
from ..faults import (
    CATALOGUE,
    FAULT_NAMES,
    FAULTS,
    LAYOUTS,
    QUANTITIES,
    flat_from_nested,
    healthy_values,
    severity,
)
from ..identification.confidence import Z90, severity_interval

#: The estimated quantities a history table holds: every fault quantity but the angles.
TABLE_COLUMNS = tuple(name for name, q in QUANTITIES.items() if not q.circular)
FAULT_LIMIT = 0.9  # [-] fractions and magnitudes ending below 1 (open range) are capped here


class HistoryTable(NamedTuple):
    actuator: str
    source: str
    usage: np.ndarray  # [h], strictly increasing
    severity: dict[str, np.ndarray]  # estimated severity per fault at each inspection
    truth: dict[str, np.ndarray] | None  # true severity (synthetic histories only)
    failure_usage: dict[str, float] | None  # [h] true usage at the failure threshold
    #: per fault, each inspection's own standard deviation of the severity (from its 90 %
    #: interval); NaN where the inspection has none (a report of an older emaprog, a table)
    sigma: dict[str, np.ndarray] | None = None


def severity_sigma(fault: str, interval: dict[str, tuple[float, float] | None]) -> float:
    """A fault's severity standard deviation from its quantities' 90 % intervals (NaN: none)."""
    known = {q: v for q, v in interval.items() if v is not None}
    if any(q.name not in known for q in FAULTS[fault].magnitudes):
        return math.nan
    low, high = severity_interval(fault, known)
    return (high - low) / (2.0 * Z90)


def _interval_of(report: dict) -> dict[str, tuple[float, float] | None]:
    """A report's ``interval`` key flattened like its estimate ({} when it has none)."""
    tree = report.get("interval")
    if not isinstance(tree, dict):
        return {}
    out = {}
    for fault in CATALOGUE:
        value = tree.get(fault.name)
        for q in fault.quantities:
            item = value if q.key is None else (value or {}).get(q.key)
            out[q.name] = (float(item[0]), float(item[1])) if item is not None else None
    return out


def _sigmas(intervals: list[dict[str, tuple[float, float] | None]]) -> dict[str, np.ndarray]:
    return {f: np.array([severity_sigma(f, i) for i in intervals]) for f in FAULT_NAMES}


def _severities(values: list[dict[str, float]]) -> dict[str, np.ndarray]:
    return {f: np.array([severity(f, v) for v in values]) for f in FAULT_NAMES}


def _check_usage(usage: np.ndarray, source: str | Path, key: str) -> None:
    if usage.size < 3:
        raise InputError(source, f"a history needs at least 3 inspections, got {usage.size}", key)
    if not np.all(np.isfinite(usage)) or np.any(usage < 0):
        raise InputError(source, "usage must be finite and >= 0 flight hours", key)
    if np.any(np.diff(usage) <= 0):
        raise InputError(
            source,
            "inspections must be sorted by usage, each usage once (strictly increasing)",
            key,
        )


def read_table(path: str | Path) -> HistoryTable:
    """A Parquet history table (module docstring); any problem is an InputError."""
    path = Path(path)
    try:
        table = pq.read_table(path)
    except (pa.ArrowInvalid, OSError) as exc:
        raise InputError(
            path, f"is not a readable Parquet history ({str(exc).splitlines()[0]})"
        ) from None
    names = table.column_names
    missing = [c for c in ("actuator", "usage", *TABLE_COLUMNS) if c not in names]
    if missing:
        raise InputError(
            path,
            f"missing column(s) {', '.join(missing)}; a history table needs "
            f"actuator, usage, {', '.join(TABLE_COLUMNS)}",
        )
    actuators = sorted({str(a) for a in table.column("actuator").to_pylist()})
    if len(actuators) != 1:
        raise InputError(
            path,
            f"holds {len(actuators)} actuators ({', '.join(actuators[:5])}); "
            "a history is one actuator's: split the table",
            "actuator",
        )
    columns = {}
    for name in ("usage", *TABLE_COLUMNS):
        column = table.column(name)
        if column.null_count or not (
            pa.types.is_floating(column.type) or pa.types.is_integer(column.type)
        ):
            raise InputError(path, "must be numbers with no missing value", name)
        columns[name] = column.to_numpy().astype(float)
        if not np.all(np.isfinite(columns[name])):
            raise InputError(path, "holds NaN or infinite values", name)
    _check_usage(columns["usage"], path, "usage")
    values = [
        {**healthy_values(), **{c: float(columns[c][k]) for c in TABLE_COLUMNS}}
        for k in range(columns["usage"].size)
    ]
    return HistoryTable(actuators[0], str(path), columns["usage"], _severities(values), None, None)


def read_reports(folder: str | Path) -> HistoryTable:
    """The ``report.json`` files under ``folder``, ordered by their inspection usage."""
    folder = Path(folder)
    files = sorted(folder.rglob("report.json"))
    if not files:
        raise InputError(
            folder,
            "holds no report.json (write them with `emaprog identify TRACE "
            "--actuator ID --usage HOURS -o DIR`)",
        )
    entries = []
    for path in files:
        try:
            report = json.loads(path.read_text())
            inspection = report["inspection"]
            actuator, usage = str(inspection["actuator"]), float(inspection["usage"])
            values = flat_from_nested(report["estimate"])
        except (json.JSONDecodeError, UnicodeDecodeError):
            raise InputError(path, "is not valid JSON") from None
        except (KeyError, TypeError, ValueError):
            raise InputError(
                path,
                "lacks inspection.actuator, inspection.usage or a full estimate "
                "(identify with --actuator ID --usage HOURS)",
                "inspection",
            ) from None
        entries.append((usage, actuator, values, path, _interval_of(report)))
    actuators = sorted({e[1] for e in entries})
    if len(actuators) != 1:
        raise InputError(
            folder,
            f"mixes actuators ({', '.join(actuators[:5])}); a history is one actuator's reports",
            "inspection.actuator",
        )
    entries.sort(key=lambda e: e[0])
    usages = np.array([e[0] for e in entries])
    repeated = [str(e[3]) for a, e in zip(entries, entries[1:]) if e[0] == a[0]]
    if repeated:
        raise InputError(repeated[0], "repeats the usage of another report", "inspection.usage")
    _check_usage(usages, folder, "inspection.usage")
    return HistoryTable(
        actuators[0],
        str(folder),
        usages,
        _severities([e[2] for e in entries]),
        None,
        None,
        _sigmas([e[4] for e in entries]),
    )


# ---------------------------------------------------------------- synthetic histories
class Degradation(NamedTuple):
    """One fault's realised growth law in a synthetic history."""

    law: str
    initial: float
    rate: float  # the history's draw (law rate x lognormal variability)


def realised_laws(history: History) -> dict[str, Degradation]:
    """Each growing fault's law with its rate drawn from the history seed (fixed order)."""
    rng = np.random.default_rng(np.random.SeedSequence(history.seed))
    draws = rng.standard_normal(len(FAULT_NAMES))
    laws = {}
    for fault, z in zip(FAULT_NAMES, draws):
        spec = getattr(history.growth, fault)
        if spec is not None:
            laws[fault] = Degradation(
                spec.law, spec.initial, spec.rate * math.exp(spec.variability * z)
            )
    return laws


def _severity_at(law: Degradation, usage: float) -> float:
    if law.law == "linear":
        return law.initial + law.rate * usage
    return law.initial * math.exp(min(law.rate * usage, 700.0))


def true_faults(history: History, laws: dict[str, Degradation], usage: float) -> Faults:
    """The actuator's faults at ``usage`` [h] (capped to the fault ranges)."""
    value: dict[str, Any] = {}
    for fault in CATALOGUE:
        law = laws.get(fault.name)
        level = _severity_at(law, usage) if law is not None else 0.0
        growth = getattr(history.growth, fault.name) if law is not None else None
        value[fault.name] = LAYOUTS[fault.layout].grown(fault, level, growth, FAULT_LIMIT)
    return Faults.model_validate(value)


def failure_usage(law: Degradation, threshold: float) -> float:
    """True usage at which a realised law reaches ``threshold`` [h] (inf: never)."""
    if law.initial >= threshold:
        return 0.0
    if law.rate <= 0 or (law.law == "exponential" and law.initial <= 0):
        return math.inf
    if law.law == "linear":
        return (threshold - law.initial) / law.rate
    return math.log(threshold / law.initial) / law.rate


def history_hash(history: History, base: Scenario, params: Parameters) -> str:
    content = {
        "history": history.model_dump(mode="json", exclude={"scenario"}),
        "scenario": base.model_dump(mode="json"),
        "parameters": params.values(),
    }
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()


def inspection_specs(
    history: History, base: Scenario, params: Parameters, digest: str, indices: list[int]
) -> list[campaigns.CaseSpec]:
    """One case per inspection: the true faults at its usage, its own noise and GA seeds."""
    laws = realised_laws(history)
    settings = history.identify if "identify" in history.model_fields_set else base.identify
    specs = []
    for k in indices:
        usage = history.inspections.start + k * history.inspections.step
        rng = np.random.default_rng(np.random.SeedSequence(history.seed, spawn_key=(k,)))
        noise_seed, ga_seed = (int(s) for s in rng.integers(0, campaigns.SEED_LIMIT, size=2))
        specs.append(
            campaigns.make_spec(
                k,
                False,
                f"{history.actuator}-{k}",
                base,
                true_faults(history, laws, usage),
                noise_seed,
                ga_seed,
                settings,
                params,
                digest,
            )
        )
    return specs


def from_cases(
    history: History, params: Parameters, store: campaigns.CaseStore, source: str
) -> HistoryTable:
    """The history table of a finished synthetic history (truth included)."""
    frame = store.read()
    usage = history.inspections.start + frame["case_id"].to_numpy(float) * history.inspections.step
    estimated = [{q: float(row[f"est_{q}"]) for q in QUANTITIES} for _, row in frame.iterrows()]
    true = [{q: float(row[f"true_{q}"]) for q in QUANTITIES} for _, row in frame.iterrows()]
    laws = realised_laws(history)
    failure = {
        f: failure_usage(law, getattr(params.spec.health, f).failure) for f, law in laws.items()
    }
    intervals = [
        {
            q: (float(row[f"low_{q}"]), float(row[f"high_{q}"]))
            if f"low_{q}" in row and np.isfinite(row[f"low_{q}"])
            else None
            for q in QUANTITIES
        }
        for _, row in frame.iterrows()
    ]
    return HistoryTable(
        history.actuator,
        source,
        usage,
        _severities(estimated),
        _severities(true),
        failure,
        _sigmas(intervals),
    )
