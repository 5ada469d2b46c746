"""The resumable case dataset of a campaign's results folder (docs/reference.md, Campaign results)."""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ..config.parameters import Parameters
from ..config.scenario import Campaign, Scenario
from ..errors import InputError
from ..io.storage import write_json
from .execution import Failure
from .sampling import identify_settings

CASE_FILE = "case-{:06d}"
TIMING_COLUMNS = ("simulate_s", "identify_s")


def campaign_hash(campaign: Campaign, base: Scenario, params: Parameters) -> str:
    """Hash of what decides the cases' numbers: campaign, base scenario, parameter values."""
    content = {
        "campaign": campaign.model_dump(mode="json", exclude={"scenario"}),
        "identify": identify_settings(campaign, base).model_dump(mode="json"),
        "scenario": base.model_dump(mode="json"),
        "parameters": params.values(),
    }
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()


class CaseStore:
    """The results folder of one campaign: manifest, one Parquet file per case, failures."""

    def __init__(self, folder: str | Path):
        self.folder = Path(folder)
        self.cases = self.folder / "cases"
        self.failures = self.folder / "failures"
        self.manifest = self.folder / "manifest.json"

    def finished(self) -> set[int]:
        """Ids of the cases whose file is complete (temporaries are dot-names, never listed)."""
        if not self.cases.is_dir():
            return set()
        return {int(p.stem.split("-")[1]) for p in self.cases.glob("case-*.parquet")}

    def failed(self) -> dict[int, str]:
        if not self.failures.is_dir():
            return {}
        out = {}
        for path in sorted(self.failures.glob("case-*.json")):
            out[int(path.stem.split("-")[1])] = json.loads(path.read_text())["error"]
        return out

    def open(self, source: Path, digest: str, manifest: dict, resume: bool) -> None:
        """Start or continue the campaign in this folder; refuses to mix campaigns.

        ``digest`` hashes what decides the cases' numbers; it is stored in the
        manifest as ``content_hash`` and must match on ``resume``.
        """
        if self.manifest.is_file():
            try:
                stored = json.loads(self.manifest.read_text())["content_hash"]
            except (json.JSONDecodeError, KeyError, UnicodeDecodeError):
                raise InputError(
                    self.manifest,
                    "is not a readable campaign manifest; choose another results folder",
                ) from None
            if not resume:
                raise InputError(
                    self.folder,
                    "already holds a campaign's results; pass --resume to "
                    "continue it, or choose another results folder (-o)",
                )
            if stored != digest:
                raise InputError(
                    source,
                    "changed since the first run in "
                    f"{self.folder} (campaign, base scenario or parameter values "
                    "differ); --resume only continues the same campaign: use another "
                    "results folder (-o)",
                )
        elif self.finished():
            raise InputError(
                self.folder,
                "holds case files but no manifest.json; choose another results folder (-o)",
            )
        self.cases.mkdir(parents=True, exist_ok=True)
        for stale in self.cases.glob(".case-*"):  # temporaries of a killed run
            stale.unlink()
        if not self.manifest.is_file():
            write_json(self.manifest, {**manifest, "content_hash": digest})

    def write_case(self, row: dict, provenance: dict) -> Path:
        """One case as its own Parquet file, atomically, with provenance in the file metadata."""
        table = pa.Table.from_pylist([row])
        table = table.replace_schema_metadata({b"emaprog": json.dumps(provenance).encode()})
        name = CASE_FILE.format(row["case_id"])
        tmp = self.cases / f".{name}.{os.getpid()}.tmp"
        try:
            pq.write_table(table, tmp)
            os.replace(tmp, self.cases / f"{name}.parquet")
        except BaseException:  # Ctrl-C or a full disk mid-write: leave no temporary behind
            tmp.unlink(missing_ok=True)
            raise
        stale_failure = self.failures / f"{name}.json"
        if stale_failure.exists():
            stale_failure.unlink()
        return self.cases / f"{name}.parquet"

    def write_failure(self, failure: Failure) -> Path:
        self.failures.mkdir(parents=True, exist_ok=True)
        return write_json(
            self.failures / f"{CASE_FILE.format(failure.case_id)}.json", failure._asdict()
        )

    def read(self) -> pd.DataFrame:
        """All finished cases, sorted by case id."""
        files = sorted(self.cases.glob("case-*.parquet"))
        if not files:
            return pd.DataFrame()
        frame = pd.concat([pq.read_table(f).to_pandas() for f in files], ignore_index=True)
        return frame.sort_values("case_id", kind="stable").reset_index(drop=True)


#: What an executor hands each finished case (or its failure) to.
OnResult = Callable[[dict | Failure], None]
