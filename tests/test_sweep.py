"""Monte-Carlo campaigns: sampling, resumable storage, local pool, Dask, summary, baseline.

The campaigns here are short (0.2 s sine, a 16 x 4 GA without refinement) so
that a case takes a fraction of a second: these tests check the machinery
(seeds, storage, resume, execution back-ends), not identification accuracy,
which tests/test_identify.py and the regression campaign check.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from emaprog import api
from emaprog.campaign import cases as campaigns
from emaprog.campaign.summary import compare, summarize
from emaprog.cli import app
from emaprog.config import parameters
from emaprog.config.scenario import load_campaign

from .conftest import ROOT

runner = CliRunner()
TIMINGS = ["simulate_s", "identify_s"]

TINY = {
    "name": "tiny",
    "cases": 8,
    "seed": 11,
    "scenario": {
        "name": "tiny-base",
        "duration": 0.2,
        "seed": 0,
        "command": {"kind": "sine", "amplitude": 0.05, "frequency": 4.0},
    },
    "faults": {
        "friction": {"uniform": [1.0, 3.0]},
        "backlash": {"uniform": [0.0, 1.0e-3]},
        "short_circuit": {"phase": "any", "fraction": {"uniform": [0.0, 0.4]}},
        "eccentricity": {"zeta": {"uniform": [0.0, 0.5]}},
        "healthy_fraction": 0.25,
    },
    "identify": {"ga": {"population": 16, "generations": 4}, "refine": False},
}


def write_campaign(folder: Path, **changes) -> Path:
    path = folder / f"{changes.get('name', 'tiny')}.yaml"
    path.write_text(yaml.safe_dump({**TINY, **changes}))
    return path


def cases(folder: Path) -> pd.DataFrame:
    """The case table without its timings (the only columns that may differ between runs)."""
    return campaigns.CaseStore(folder).read().drop(columns=TIMINGS)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The tiny campaign run once, uninterrupted, in this process: the reference result."""
    folder = tmp_path_factory.mktemp("tiny")
    path = write_campaign(folder)
    outcome = api.sweep(path, folder / "serial", workers=1, show_progress=False)
    return path, outcome


# ---------------------------------------------------------------- sampling
def test_cases_are_keyed_by_index_and_respect_their_distributions(tmp_path):
    campaign, _ = load_campaign(write_campaign(tmp_path, cases=400))
    forward = [campaigns.sample_case(campaign, k) for k in range(400)]
    backward = [campaigns.sample_case(campaign, k) for k in reversed(range(400))][::-1]
    assert forward == backward  # order of evaluation does not matter
    healthy = [c for c in forward if c[0]]
    assert 0.18 < len(healthy) / 400 < 0.32  # healthy_fraction 0.25, binomial 3 sigma
    assert all(c[1].friction == 1.0 and c[1].short_circuit.a == 0.0 for c in healthy)
    faulty = [c[1] for c in forward if not c[0]]
    assert all(1.0 <= f.friction <= 3.0 and 0.0 <= f.backlash <= 1e-3 for f in faulty)
    # one shorted phase per faulty case, each phase about a third of the time
    shorted = [[x for x in "abc" if getattr(f.short_circuit, x) > 0] for f in faulty]
    assert all(len(s) == 1 for s in shorted)
    counts = {x: sum(s == [x] for s in shorted) for x in "abc"}
    assert min(counts.values()) > 0.25 * len(faulty)
    noise_seeds = {c[2] for c in forward}
    assert len(noise_seeds) == 400  # every case its own noise


def test_a_named_phase_is_the_only_one_shorted(tmp_path):
    faults = {
        **TINY["faults"],
        "short_circuit": {"phase": "b", "fraction": {"uniform": [0.1, 0.2]}},
    }
    campaign, _ = load_campaign(write_campaign(tmp_path, faults=faults, cases=30))
    for k in range(30):
        healthy, f, _, _ = campaigns.sample_case(campaign, k)
        if not healthy:
            assert f.short_circuit.a == f.short_circuit.c == 0.0 and 0.1 <= f.short_circuit.b <= 0.2


# ---------------------------------------------------------------- results
def test_sweep_writes_one_file_per_case_with_spec_columns_and_summary(tiny):
    path, outcome = tiny
    folder = outcome.folder
    files = sorted((folder / "cases").glob("*.parquet"))
    assert [f.name for f in files] == [f"case-{k:06d}.parquet" for k in range(8)]
    frame = campaigns.CaseStore(folder).read()
    for quantity in (
        "friction",
        "backlash",
        "short_circuit_a",
        "short_circuit_b",
        "short_circuit_c",
        "eccentricity_zeta",
        "eccentricity_phase",
    ):
        for prefix in ("true", "est", "err"):
            assert f"{prefix}_{quantity}" in frame.columns
    for column in ("case_id", "noise_seed", "ga_seed", "fitness", "health_friction", *TIMINGS):
        assert column in frame.columns
    err = frame["est_friction"] - frame["true_friction"]
    assert np.allclose(err, frame["err_friction"])
    import pyarrow.parquet as pq

    meta = json.loads(pq.read_schema(files[0]).metadata[b"emaprog"])
    assert meta["campaign_hash"] == outcome.summary["campaign_hash"] and meta["case_id"] == 0
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["finished"] == 8 and summary["failed"] == 0
    # the libraries and CPU the numbers came from, in the summary, the manifest and each case
    for record in (summary, json.loads((folder / "manifest.json").read_text()), meta):
        assert {"numpy", "scipy", "numba", "cpu"} <= set(record["environment"])
    assert summary["environment"]["cpu"] in (folder / "summary.md").read_text()
    assert (folder / "parity.png").stat().st_size > 10_000
    assert (folder / "errors.png").stat().st_size > 10_000
    assert "parity.png" in (folder / "summary.md").read_text()


def test_local_pool_gives_the_same_cases_as_one_process(tiny, tmp_path):
    path, outcome = tiny
    api.sweep(path, tmp_path / "pool", workers=2, show_progress=False)
    pd.testing.assert_frame_equal(cases(tmp_path / "pool"), cases(outcome.folder))


def test_resume_refuses_a_changed_campaign_and_a_used_folder(tiny, tmp_path):
    path, outcome = tiny
    again = runner.invoke(app, ["sweep", str(path), "-o", str(outcome.folder)])
    assert again.exit_code == 2 and "--resume" in again.output
    changed = write_campaign(tmp_path, seed=12)
    result = runner.invoke(app, ["sweep", str(changed), "-o", str(outcome.folder), "--resume"])
    assert result.exit_code == 2 and "changed since the first run" in result.output
    resumed = runner.invoke(app, ["sweep", str(path), "-o", str(outcome.folder), "--resume"])
    assert resumed.exit_code == 0 and "0 run now, 8 from earlier runs" in resumed.output


def _default_sigint() -> None:
    """A child's Ctrl-C as at a terminal, even under a runner started in the background (a
    shell starts background jobs with SIGINT ignored, and children inherit that)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start_sweep(path: Path, folder: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(
        [sys.executable, "-m", "emaprog", "sweep", str(path), "-o", str(folder), "--workers", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,
        preexec_fn=_default_sigint,
    )


def _wait_for_cases(folder: Path, count: int, process: subprocess.Popen, limit: float = 120.0):
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        if len(list((folder / "cases").glob("case-*.parquet"))) >= count:
            return
        assert process.poll() is None, process.communicate()
        time.sleep(0.02)
    raise AssertionError(f"no {count} cases after {limit} s")


def test_killed_sweep_resumes_to_the_uninterrupted_result(tiny, tmp_path):
    path, outcome = tiny
    slow = write_campaign(tmp_path, cases=16)  # same first 8 cases, more work to interrupt
    folder = tmp_path / "killed"
    process = _start_sweep(slow, folder)
    _wait_for_cases(folder, 2, process)
    os.killpg(process.pid, signal.SIGKILL)  # the sweep and its workers, as in a crash
    process.wait()
    survived = campaigns.CaseStore(folder).finished()
    assert 2 <= len(survived) < 16
    result = runner.invoke(
        app, ["sweep", str(slow), "-o", str(folder), "--resume", "--workers", "2"]
    )
    assert result.exit_code == 0, result.output
    assert f"{16 - len(survived)} run now, {len(survived)} from earlier runs" in result.output
    frame = cases(folder)
    assert list(frame["case_id"]) == list(range(16))  # every case exactly once
    pd.testing.assert_frame_equal(frame.iloc[:8].reset_index(drop=True), cases(outcome.folder))


def test_ctrl_c_stops_cleanly_and_says_how_to_resume(tmp_path):
    path = write_campaign(tmp_path, cases=16)
    folder = tmp_path / "interrupted"
    process = _start_sweep(path, folder)
    _wait_for_cases(folder, 1, process)
    os.killpg(process.pid, signal.SIGINT)  # Ctrl-C reaches the whole foreground group
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    assert "--resume" in err and "Traceback" not in err
    assert not list((folder / "cases").glob(".case-*"))  # no temporary left behind
    stored = campaigns.CaseStore(folder).read()
    assert len(stored) == len(campaigns.CaseStore(folder).finished()) >= 1


def _group_alive(group: int) -> bool:
    try:
        os.killpg(group, 0)
    except ProcessLookupError:
        return False
    return True


def test_sigterm_to_the_sweep_alone_stops_its_workers_too(tmp_path):
    """`kill PID` (or a batch scheduler's stop) reaches only the parent; its pool workers
    must not go on computing unseen. Limit 30 s: a terminated worker ends at once, the
    multiprocessing resource tracker when its pipe closes."""
    path = write_campaign(tmp_path, cases=16)
    folder = tmp_path / "terminated"
    process = _start_sweep(path, folder)
    _wait_for_cases(folder, 1, process)
    process.send_signal(signal.SIGTERM)  # the parent only, not its group
    _, err = process.communicate(timeout=60)
    assert process.returncode == 143, err
    assert "SIGTERM" in err and "--resume" in err and "Traceback" not in err
    deadline = time.monotonic() + 30.0
    while _group_alive(process.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    alive = _group_alive(process.pid)
    if alive:
        os.killpg(process.pid, signal.SIGKILL)
    assert not alive, "pool workers outlived the terminated sweep"
    assert not list((folder / "cases").glob(".case-*"))  # no temporary left behind
    stored = campaigns.CaseStore(folder).read()
    assert len(stored) == len(campaigns.CaseStore(folder).finished()) >= 1


def test_a_failing_case_is_recorded_and_retried_on_resume(tiny, tmp_path, monkeypatch):
    path, outcome = tiny
    real = campaigns.run_case

    def broken(spec):
        if spec.case_id == 3:
            raise FloatingPointError("diverged")
        return real(spec)

    from emaprog.campaign import execution  # where run_case_safely looks run_case up

    monkeypatch.setattr(execution, "run_case", broken)
    first = api.sweep(path, tmp_path / "fail", workers=1, show_progress=False)
    assert first.failed == 1 and first.summary["finished"] == 7
    record = json.loads((tmp_path / "fail" / "failures" / "case-000003.json").read_text())
    assert "FloatingPointError: diverged" in record["error"] and "Traceback" in record["traceback"]
    monkeypatch.setattr(execution, "run_case", real)
    second = api.sweep(path, tmp_path / "fail", workers=1, resume=True, show_progress=False)
    assert second.ran == 1 and second.failed == 0
    assert not (tmp_path / "fail" / "failures" / "case-000003.json").exists()
    pd.testing.assert_frame_equal(cases(tmp_path / "fail"), cases(outcome.folder))


def test_dask_local_cluster_runs_the_same_cases(tiny, tmp_path):
    distributed = pytest.importorskip("distributed")
    path, outcome = tiny
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        result = api.sweep(
            path, tmp_path / "dask", scheduler=cluster.scheduler_address, show_progress=False
        )
    assert result.summary["run"]["scheduler"].startswith("tcp://127.0.0.1")
    pd.testing.assert_frame_equal(cases(tmp_path / "dask"), cases(outcome.folder))


def test_unreachable_scheduler_is_invalid_input_and_writes_nothing(tiny, tmp_path):
    path, _ = tiny
    result = runner.invoke(
        app, ["sweep", str(path), "-o", str(tmp_path / "x"), "--scheduler", "tcp://127.0.0.1:9"]
    )
    assert result.exit_code == 2 and "--scheduler" in result.output
    assert not (tmp_path / "x").exists()


# ---------------------------------------------------------------- summary and baseline
def _frame(rows: list[dict]) -> pd.DataFrame:
    base = {
        "healthy_case": False,
        "simulate_s": 0.1,
        "identify_s": 1.0,
        "true_short_circuit_phase": "none",
        "est_short_circuit_phase": "none",
    }
    for fault in ("friction", "backlash", "short_circuit", "eccentricity"):
        base[f"health_{fault}"] = base[f"true_health_{fault}"] = "nominal"
    for q, healthy in (
        ("friction", 1.0),
        ("backlash", 0.0),
        ("short_circuit_a", 0.0),
        ("short_circuit_b", 0.0),
        ("short_circuit_c", 0.0),
        ("eccentricity_zeta", 0.0),
        ("eccentricity_phase", 0.0),
    ):
        base[f"true_{q}"] = base[f"est_{q}"] = healthy
        base[f"err_{q}"] = 0.0
    return pd.DataFrame([{**base, **row} for row in rows])


def test_summary_counts_detections_false_alarms_and_isolation():
    params = parameters.load("default")
    frame = _frame(
        [
            {"healthy_case": True},  # correct healthy
            {"healthy_case": True, "health_backlash": "incipient"},  # false alarm
            {
                "true_health_short_circuit": "degraded",
                "health_short_circuit": "degraded",
                "true_short_circuit_phase": "b",
                "est_short_circuit_phase": "b",
                "true_short_circuit_b": 0.3,
                "est_short_circuit_b": 0.32,
                "err_short_circuit_b": 0.02,
            },
            {
                "true_health_short_circuit": "incipient",
                "health_short_circuit": "nominal",
                "true_short_circuit_phase": "c",
                "true_short_circuit_c": 0.1,
                "err_short_circuit_c": -0.1,
            },
            {
                "true_health_friction": "degraded",
                "health_friction": "degraded",
                "true_friction": 2.0,
                "est_friction": 2.2,
                "err_friction": 0.2,
            },
        ]
    )
    s = summarize(frame, params)
    assert s["false_alarms"]["healthy_cases"] == 2 and s["false_alarms"]["rate"] == 0.5
    assert s["false_alarms"]["per_fault_on_healthy"]["backlash"] == 0.5
    assert s["detection"]["short_circuit"] == {"cases": 2, "detected": 1, "rate": 0.5}
    assert s["detection"]["friction"]["rate"] == 1.0 and s["detection"]["backlash"]["rate"] is None
    isolation = s["isolation"]["short_circuit"]
    assert isolation["confusion"]["b"]["b"] == 1 and isolation["confusion"]["c"]["none"] == 1
    assert isolation["correct_rate"] == 0.5
    friction = s["errors"]["friction"]  # relative: 0.2 / 2.0 on one case, 0 elsewhere
    assert friction["max"] == pytest.approx(0.1) and friction["within_tolerance"] == pytest.approx(
        0.8
    )
    assert s["errors"]["short_circuit_c"]["max"] == pytest.approx(0.1)


def test_compare_flags_only_figures_worse_than_their_tolerance():
    params = parameters.load("default")
    frame = _frame(
        [
            {
                "true_health_friction": "degraded",
                "health_friction": "degraded",
                "true_friction": 2.0,
                "est_friction": 2.02,
                "err_friction": 0.02,
            }
        ]
    )
    base = summarize(frame, params)
    assert compare(base, base) == []
    slightly = json.loads(json.dumps(base))
    slightly["errors"]["friction"]["p95"] *= 1.1  # within 25 % growth
    assert compare(slightly, base) == []
    worse = json.loads(json.dumps(base))
    worse["errors"]["friction"]["p95"] = 0.05
    worse["detection"]["friction"]["rate"] = 0.5
    lines = compare(worse, base)
    assert len(lines) == 2 and lines[0].startswith("errors.friction.p95")
    assert any(line.startswith("detection.friction.rate") for line in lines)


def test_baseline_regression_exits_3_and_bad_baseline_exits_2(tiny, tmp_path):
    path, outcome = tiny
    summary = json.loads((outcome.folder / "summary.json").read_text())
    same = tmp_path / "same.json"
    same.write_text(json.dumps(summary))
    ok = runner.invoke(
        app, ["sweep", str(path), "-o", str(outcome.folder), "--resume", "--baseline", str(same)]
    )
    assert ok.exit_code == 0 and "no figure worse" in ok.output
    better = json.loads(json.dumps(summary))
    better["errors"]["backlash"]["p95"] = 0.0
    better["false_alarms"]["rate"] = 0.0
    better_path = tmp_path / "better.json"
    better_path.write_text(json.dumps(better))
    regressed = runner.invoke(
        app,
        ["sweep", str(path), "-o", str(outcome.folder), "--resume", "--baseline", str(better_path)],
    )
    assert regressed.exit_code == 3 and "errors.backlash.p95" in regressed.output
    junk = tmp_path / "junk.json"
    junk.write_text('{"errors": 1}')
    bad = runner.invoke(
        app, ["sweep", str(path), "-o", str(outcome.folder), "--resume", "--baseline", str(junk)]
    )
    assert bad.exit_code == 2 and "junk.json" in bad.output


@pytest.mark.slow
def test_regression_campaign_meets_its_committed_baseline(tmp_path):
    """The baseline's figures, and 90 % intervals that hold the truth: at least 6 of the
    10 cases per quantity (at a true 90 %, 5 or fewer happens with 0.16 % probability) and
    80 % of all quantities' cases together (at 90 %, under 80 % of 66 happens with about
    0.5 %; the laws were calibrated on other campaigns; measured 59 of 66, friction 7 of 10
    with one case covered by 0.001: 7 of 10 per quantity would fail on a machine whose
    rounding moves that case), and a median width within twice the tolerance."""
    campaign = ROOT / "campaigns" / "regression.yaml"
    baseline = ROOT / "campaigns" / "regression-baseline.json"
    result = runner.invoke(
        app,
        ["sweep", str(campaign), "-o", str(tmp_path / "regression"), "--baseline", str(baseline)],
    )
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "regression" / "summary.json").read_text())
    blocks = summary["intervals"]["quantities"]
    held = sum(b["coverage"] * b["n"] for b in blocks.values() if b["n"])
    assert held >= 0.8 * sum(b["n"] for b in blocks.values()), blocks
    for name, block in blocks.items():
        if block["n"] >= 5:
            assert block["coverage"] >= 0.6, (name, block)
        if block["width_bar"] is not None:
            assert block["median_width"] <= block["width_bar"], (name, block)


def test_a_baseline_from_before_per_phase_faults_were_named_still_compares(tmp_path):
    """A summary.json written when ``isolation`` was the short circuit's alone reads as
    that fault's, with the same regression figures as today's shape."""
    from emaprog.campaign.run import read_baseline
    from emaprog.campaign.summary import regression_figures

    today = json.loads((ROOT / "campaigns" / "regression-baseline.json").read_text())
    old = {**today, "isolation": today["isolation"]["short_circuit"]}
    path = tmp_path / "old-summary.json"
    path.write_text(json.dumps(old))
    read = read_baseline(path)
    assert read["isolation"] == today["isolation"]
    assert regression_figures(read) == regression_figures(today)


@pytest.mark.slow
def test_no_healthy_actuator_is_flagged_faulty(tmp_path):
    """Figures of merit: 0 of 20 healthy traces flagged faulty (each with its own sensor noise)."""
    outcome = api.sweep(
        ROOT / "campaigns" / "false-alarms.yaml", tmp_path / "fa", show_progress=False
    )
    alarms = outcome.summary["false_alarms"]
    assert alarms["healthy_cases"] == 20 and alarms["flagged"] == 0, alarms
    # a healthy unit on the standard chirp is a conclusive recording: nothing inconclusive
    assert set(outcome.summary["intervals"]["inconclusive"].values()) == {0.0}


def test_sweep_workers_import_no_plotting_library():
    """A worker process imports the case runner (and the CLI module, as spawn does):
    neither may pull in matplotlib, which costs every worker start-up time and memory."""
    import subprocess
    import sys

    code = (
        "import sys, emaprog.cli, emaprog.campaign.cases; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'matplotlib'))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_unit_spread_and_hinge_moment_draws_keep_old_campaigns_and_stay_in_range():
    """actuator_spread / hinge_moment / hinge_stiffness draws come after every earlier draw
    of a case: a campaign without them samples exactly the faults and seeds it did before
    (and a campaign without springs the same units and hinge moments); with them each
    factor, hinge moment and spring lies in its range, and the case's unit is that set.
    Commissioning from three recordings keeps the unit, the loads and the first
    recording, and draws the other two on seeds and loads of their own."""
    from emaprog.campaign.cases import case_specs, sample_case, sample_unit
    from emaprog.config.scenario import Uniform, load_campaign

    quick, base = load_campaign(ROOT / "campaigns" / "quick.yaml")
    robust, _ = load_campaign(ROOT / "campaigns" / "robustness.yaml")
    same_seed = robust.model_copy(update={"seed": quick.seed, "faults": quick.faults})
    sprung = robust.model_copy(update={"hinge_stiffness": Uniform(uniform=(0.0, 3000.0))})
    three = sprung.model_copy(update={"commission": 3})
    for k in range(20):
        assert sample_case(quick, k) == sample_case(same_seed, k)
        factors, hinge, spring, (commissioning,) = sample_unit(quick, k)
        assert set(factors.values()) == {1.0} and hinge == 0.0 and spring == 0.0
        factors, hinge, spring, (commissioning,) = sample_unit(robust, k)
        for name, factor in factors.items():
            lo, hi = getattr(robust.actuator_spread, name).uniform
            assert 1.0 + lo <= factor <= 1.0 + hi
        assert -100.0 <= hinge <= 100.0 and -100.0 <= commissioning.hinge_moment <= 100.0
        assert spring == 0.0 and commissioning.hinge_stiffness == 0.0
        with_springs = sample_unit(sprung, k)
        assert with_springs[:2] == (factors, hinge)
        assert with_springs[3][0].hinge_moment == commissioning.hinge_moment
        assert (
            0.0 <= with_springs[2] <= 3000.0 and 0.0 <= with_springs[3][0].hinge_stiffness <= 3000.0
        )
        with_three = sample_unit(three, k)
        assert with_three[:3] == with_springs[:3] and with_three[3][0] == with_springs[3][0]
        assert len(with_three[3]) == 3 and len({c.seed for c in with_three[3]}) == 3
        for drawn in with_three[3]:
            assert -100.0 <= drawn.hinge_moment <= 100.0
            assert 0.0 <= drawn.hinge_stiffness <= 3000.0
    from emaprog.config import parameters

    params = parameters.load("default")
    spec = next(case_specs(robust, base, params, "h", [3]))
    factors, hinge, _, _ = sample_unit(robust, 3)
    assert spec.hinge_moment == hinge and spec.commission is not None
    assert spec.unit.spec.mechanical.motor_inertia == pytest.approx(
        params.spec.mechanical.motor_inertia * factors["motor_inertia"], rel=1e-12
    )
    assert len(next(case_specs(three, base, params, "h", [3])).commission) == 3


def test_a_case_commissioned_from_two_recordings_fits_both_and_gives_both_residuals():
    """`commission: 2`: the case's unit is commissioned from two healthy recordings of its
    own (their own noise and hinge moments, as `emaprog commission` takes a rig's), each
    gets its residual against the commissioned Monitor, for the `recording` correction to
    average. The commissioned set explains both: each residual's
    current RMS is under 10 % of that recording's current RMS (the commissioning's own
    acceptance, MAX_CURRENT_RESIDUAL; measured 1.5 % on both, the recordings' noise), and
    the first recording's hinge moment (-44.6 N m drawn) is read within 5 N m (measured
    0.4 N m; 0.4-1.3 N m from one recording on the robustness campaign's units)."""
    from emaprog.campaign.cases import case_specs, commission_case
    from emaprog.campaign.sampling import load_parameters, with_hinge
    from emaprog.config.scenario import Faults, Scenario, load_campaign
    from emaprog.fitting.commission import MAX_CURRENT_RESIDUAL
    from emaprog.models import reference

    path = ROOT / "campaigns" / "robustness.yaml"
    campaign, base = load_campaign(path)
    two = campaign.model_copy(update={"commission": 2})
    spec = next(case_specs(two, base, load_parameters(path, two, base), "h", [3]))
    _, row, residuals = commission_case(spec, spec.unit)
    assert [r.source for r in residuals] == [
        "case 3 commissioning",
        "case 3 commissioning recording 2",
    ]
    assert abs(row["commission_err_hinge_moment"]) < 5.0
    for drawn, residual in zip(spec.commission, residuals, strict=True):
        healthy = Scenario.model_validate(
            {
                **base.model_dump(mode="json"),
                "faults": Faults().model_dump(mode="json"),
                "seed": drawn.seed,
            }
        )
        recorded = reference.simulate(
            with_hinge(healthy, drawn.hinge_moment, drawn.hinge_stiffness), spec.unit
        )["current"]
        rms = float(np.sqrt(np.mean(np.square(recorded))))
        assert float(np.sqrt(np.mean(np.square(residual.residual["current"])))) < (
            MAX_CURRENT_RESIDUAL * rms
        )
    assert not np.array_equal(residuals[0].residual["current"], residuals[1].residual["current"])


@pytest.mark.slow
def test_a_small_robustness_campaign_commissions_each_unit_and_stays_within_spec(tmp_path):
    """The first 4 cases of campaigns/robustness.yaml end to end (spread units, unknown
    hinge moments, each commissioned from its own healthy recording, nuisances): two faulty
    units identified within tolerance on every quantity, two healthy ones all nominal; each
    row carries its commissioning errors (k_e within 8 %: measured 0.6-5.6 % here, p95 5.9 %
    over the 50-case campaign), the estimated hinge moment within 5 N m (measured 0.4-1.3)
    and the intervals."""
    data = yaml.safe_load((ROOT / "campaigns" / "robustness.yaml").read_text())
    data.update(cases=4, scenario=str(ROOT / "configs" / "chirp-nominal.yaml"))
    path = tmp_path / "small.yaml"
    path.write_text(yaml.safe_dump(data))
    outcome = api.sweep(path, tmp_path / "out", workers=2)
    summary = outcome.summary
    for quantity, stats in summary["errors"].items():
        if stats["within_tolerance"] is not None:
            assert stats["within_tolerance"] == 1.0, (quantity, stats)
    assert summary["false_alarms"]["healthy_cases"] == 2
    assert summary["false_alarms"]["flagged"] == 0
    cases = outcome.cases
    assert (abs(cases["est_hinge_moment"] - cases["true_hinge_moment"]) < 5.0).all()
    assert (abs(cases["commission_err_back_emf_constant"]) < 0.08).all()
    assert summary["commissioning"]["back_emf_constant"]["n"] == 4
    assert (
        cases["low_friction"].notna().all()
        and (cases["low_friction"] <= cases["est_friction"]).all()
    )
    # a campaign's commissioned unit gets the rig workflow's correction (`identify -p UNIT.yaml`)
    assert (cases["correction"] == "recording").all(), cases["correction"].tolist()


def test_a_campaigns_commissioned_unit_gets_the_rig_workflows_correction():
    """`identify.nominal_correction` omitted: a campaign's commissioned unit (a scaled set that
    carries no commissioning record) gets `recording`, as `identify -p UNIT.yaml` does; the
    same set uncommissioned gets `reference`; a named correction is kept."""
    from emaprog.config.scenario import IdentifySettings
    from emaprog.identification.defaults import resolve

    shipped = parameters.load("default")
    assert shipped.spec.commissioning is None
    metadata = {"model": "reference"}
    open_settings = IdentifySettings()
    twin = resolve(open_settings, metadata, shipped)
    assert twin.settings.nominal_correction == "reference"
    unit = resolve(open_settings, metadata, shipped, real_unit=True, commissioned=True)
    assert unit.settings.nominal_correction == "recording"
    assert unit.notes["nominal_correction"] == "default for a commissioned unit"
    assert unit.settings.nuisances == ["hinge_moment", "resistance_factor"]
    named = IdentifySettings(nominal_correction="reference")
    kept = resolve(named, metadata, shipped, real_unit=True, commissioned=True)
    assert kept.settings.nominal_correction == "reference"
    assert kept.notes["nominal_correction"] == "identify.nominal_correction"
