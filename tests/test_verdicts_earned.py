"""No verdict from a recording that cannot support one: at rest, too short, mostly noise;
and the report names a faulty phase only beside a flagged short circuit."""

from __future__ import annotations

import pytest

import emaprog
from emaprog.config.scenario import load_scenario

from .conftest import CONFIGS


def report_of(name: str, **update):
    scenario = load_scenario(CONFIGS / f"{name}.yaml")
    data = scenario.model_dump(mode="json")
    for key, value in update.items():
        data[key] = value
    return emaprog.identify(emaprog.simulate(scenario.model_validate(data)))


def test_at_rest_every_fault_is_inconclusive_with_its_reason():
    """Command 0 for 0.5 s, the shipped sensor noise only: nothing is excited (peak motor
    speed far under 5 % of the limit), so no verdict; before, a 'degraded' short circuit."""
    report = report_of("chirp-nominal", command={"kind": "constant", "offset": 0.0})
    assert set(report.health.values()) == {"inconclusive"}
    why = report.data["confidence"]["inconclusive"]
    assert all("does not excite" in reason for reason in why.values()), why
    assert report.data["short_circuit_phase"] is None


def test_a_recording_too_short_to_judge_gets_no_verdict():
    """The Fig. 10 unit for 0.1 s (friction read 3.79 for 1.8 before): inconclusive, 'too short'."""
    report = report_of("fig10-multiple-faults", duration=0.1)
    assert set(report.health.values()) == {"inconclusive"}
    assert all("too short" in r for r in report.data["confidence"]["inconclusive"].values())


@pytest.mark.slow
def test_a_healthy_unit_names_no_faulty_phase():
    """All verdicts nominal: no phase, no phase confidence (report.json and report.md)."""
    from emaprog.report import report_markdown

    report = report_of("chirp-nominal")
    assert set(report.health.values()) == {"nominal"}
    assert report.data["short_circuit_phase"] is None
    assert report.data["confidence"]["isolation"] == {"short_circuit": None}
    data = {**report.data, "figures": {"fit": "fit.png", "convergence": "convergence.png"}}
    text = report_markdown(data)
    assert "no faulty phase named" in text and "Confidence in phase" not in text


def test_a_fault_seen_at_one_inspection_gets_no_remaining_useful_life(tmp_path):
    """Reports at 0, 500 and 1000 h, only the last with friction 1.6 (a step, not a trend):
    'insufficient history' and no RUL interval (before: 111 h, 90 %: 107-116 h)."""
    import json

    import pandas as pd

    table = pd.DataFrame(
        {
            "actuator": ["ema-7"] * 3,
            "usage": [0.0, 500.0, 1000.0],
            "friction": [1.01, 0.99, 1.6],
            "backlash": [0.0] * 3,
            "short_circuit_a": [0.0] * 3,
            "short_circuit_b": [0.0] * 3,
            "short_circuit_c": [0.0] * 3,
            "eccentricity_zeta": [0.0] * 3,
        }
    )
    table.to_parquet(tmp_path / "history.parquet")
    result = emaprog.trend(tmp_path / "history.parquet", tmp_path / "trend")
    friction = result.faults["friction"]
    assert friction["status"] == "insufficient history" and friction["detected_at"] == 1000.0
    assert friction["rul"] == {"median": None, "low": None, "high": None}
    assert "insufficient history" in (tmp_path / "trend" / "trend.md").read_text()
    assert json.loads((tmp_path / "trend" / "trend.json").read_text())["faults"]["friction"]["note"]


def _isolation(phase, runner_up, delta_chi2, confidence, separated):
    """A report's ``confidence.isolation`` entry for a per-phase fault."""
    return {
        "phase": phase,
        "runner_up": runner_up,
        "delta_chi2": delta_chi2,
        "confidence": confidence,
        "separated": separated,
    }


def test_a_short_circuit_split_between_two_phases_names_neither():
    """Flagged, but A and B told apart at 68 % (like a 2 kHz recording's 0.064 / 0.060): no phase
    named, the two candidates said; at 99 % the worst phase is named; unflagged, none."""
    from emaprog.identification.confidence import MIN_PHASE_CONFIDENCE, named_phase
    from emaprog.report import _phase_sentence

    values = {"short_circuit_a": 0.064, "short_circuit_b": 0.063, "short_circuit_c": 0.014}
    split = _isolation("a", "b", 1.47, 0.68, separated=False)
    clear = {**split, "confidence": 0.99}
    assert MIN_PHASE_CONFIDENCE == 0.9
    fault = "short_circuit"
    assert named_phase(values, fault, True, split) is None
    assert named_phase(values, fault, True, clear) == "a"
    assert named_phase(values, fault, False, clear) is None
    # on a unit of another form the two phases' intervals must be apart as well
    overlapping = {**clear, "separated": False}
    assert named_phase(values, fault, True, overlapping, "form") is None
    assert named_phase(values, fault, True, {**clear, "separated": True}, "form") == "a"
    assert named_phase(values, fault, True, overlapping, "unit") == "a"
    overlap_report = {
        "health": {"short_circuit": "incipient"},
        "short_circuit_phase": None,
        "confidence": {"isolation": {"short_circuit": overlapping}},
    }
    assert "intervals overlap" in _phase_sentence(overlap_report)
    report = {
        "health": {"short_circuit": "incipient"},
        "short_circuit_phase": None,
        "confidence": {"isolation": {"short_circuit": split}},
    }
    assert "phase not determined: A or B" in _phase_sentence(report)


def test_an_inconclusive_short_at_its_threshold_names_its_suspect_phase():
    """A short on C read 0.056 [0.048, 0.064] beside A and B under 0.01, inconclusive only
    because its interval does not clear the 0.05 threshold (robustness-pwm's case 64): the
    verdict stays inconclusive and names C as the suspect phase, its interval apart from the
    runner-up's; with the intervals overlapping, or inconclusive for another reason (a fit the
    Monitor does not explain), no phase is named."""
    from types import SimpleNamespace

    from emaprog.config import parameters
    from emaprog.identification.result import judge
    from emaprog.report import _phase_sentence

    values = {"short_circuit_a": 0.004, "short_circuit_b": 0.006, "short_circuit_c": 0.056}
    apart = _isolation("c", "b", 310.0, 1.0, separated=True)

    def verdict(isolation, at_threshold):
        confidence = SimpleNamespace(
            inconclusive={"short_circuit": "interval"},
            isolation={"short_circuit": isolation},
            basis="form",
            at_threshold=at_threshold,
        )
        result = SimpleNamespace(estimate=values, confidence=confidence)
        return judge(result, ["short_circuit"], parameters.load("default-pwm"))

    named = verdict(apart, ("short_circuit",))
    assert named.health["short_circuit"] == "inconclusive"
    assert named.phase["short_circuit"] == "c" and named.isolation["short_circuit"] == apart
    report = {
        "health": named.health,
        "short_circuit_phase": "c",
        "confidence": {"isolation": named.isolation},
    }
    assert "inconclusive at its incipient threshold" in _phase_sentence(report)
    assert "suspect phase C" in _phase_sentence(report)
    overlapping = verdict({**apart, "separated": False}, ("short_circuit",))
    assert overlapping.phase["short_circuit"] is None
    unexplained = verdict(apart, ())
    assert unexplained.phase["short_circuit"] is None
    assert unexplained.isolation["short_circuit"] is None


def test_off_the_calibration_an_echo_twin_widens_the_intervals():
    """A healthy twin driven by a 0.05 rad step: the Monitor reads a backlash of about 4e-5
    rad on every such twin (campaigns/off-calibration/step.yaml: 22 healthy cases, 3.8-4.6e-5),
    which the model-error laws, calibrated on the chirp, bound to +-1e-5: the interval
    excluded the true 0 in all 22. The fit is far above its floor, so an echo twin runs
    and the backlash interval holds 0; a recording of the calibration's own conditions (the
    chirp) gets no echo and keeps the laws' interval."""
    step = {"kind": "step", "amplitude": 0.05, "time": 0.05}
    report = report_of("chirp-nominal", command=step)
    echo = report.data["confidence"]["echo"]
    assert echo is not None and any("noise floor" in r for r in echo["reasons"]), echo
    low, high = report.data["interval"]["backlash"]
    assert low <= 0.0 <= high, (low, high)
    assert report_of("chirp-nominal").data["confidence"]["echo"] is None
