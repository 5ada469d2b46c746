"""Monte-Carlo fault campaigns (docs/reference.md, Campaign YAML and Campaign results): sampling, execution, and the resumable case dataset.

A campaign is ``cases`` independent twin experiments on one base scenario:
draw true faults from the campaign's distributions, simulate the noisy
Reference Model, identify the faults with the GA over the Monitor Model, and
store truth, estimate and error as one row.

Reproducibility: case ``k`` draws everything (its faults, the Reference noise
seed and the GA seed) from ``SeedSequence(seed, spawn_key=(k,))`` -- the same
stream ``SeedSequence(seed).spawn(...)`` hands its k-th child -- so a case's
numbers depend on the master seed and its index only, never on the worker that
ran it, the number of workers or the order of completion.

Storage (``RESULTS_DIR``):

* ``manifest.json`` -- the campaign, its base scenario and parameter values,
  and their hash; ``--resume`` refuses a campaign whose hash changed;
* ``cases/case-NNNNNN.parquet`` -- one file per finished case, written under a
  temporary dot-name and renamed, so a crash never leaves half a case and
  Parquet readers never see the temporary;
* ``failures/case-NNNNNN.json`` -- a case that raised: its error and
  traceback; the campaign goes on, and ``--resume`` tries it again.
"""

from __future__ import annotations

# The campaign's parts, one module each; this module keeps their names together.
from .execution import Failure, commission_case, run_case, run_case_safely
from .executors import (
    Interrupted,
    OnResult,
    connect,
    execute,
    run_case_on_dask,
    run_dask,
    run_local,
    run_serial,
    worker_count,
)
from .sampling import (
    SEED_LIMIT,
    CaseSpec,
    Commissioning,
    case_specs,
    identify_settings,
    load_parameters,
    make_spec,
    sample_case,
    sample_unit,
    with_hinge,
)
from .store import CASE_FILE, TIMING_COLUMNS, CaseStore, campaign_hash

__all__ = [
    "CASE_FILE",
    "SEED_LIMIT",
    "TIMING_COLUMNS",
    "CaseSpec",
    "CaseStore",
    "Commissioning",
    "Failure",
    "Interrupted",
    "OnResult",
    "campaign_hash",
    "case_specs",
    "commission_case",
    "connect",
    "execute",
    "identify_settings",
    "load_parameters",
    "make_spec",
    "run_case",
    "run_case_on_dask",
    "run_case_safely",
    "run_dask",
    "run_local",
    "run_serial",
    "sample_case",
    "sample_unit",
    "with_hinge",
    "worker_count",
]
