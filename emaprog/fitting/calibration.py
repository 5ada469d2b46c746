"""Calibration of the Monitor Model against the Reference Model (docs/reference.md, Calibration).

Three steps on the healthy and faulty chirp of the parameter set, all noise-free:

1. ``commutation_loss`` [s/rad]: the speed-dependent torque-per-ampere drop
   that stands for the Reference motor's commutation dips. Chosen so that the
   friction multiplier that best explains the *healthy* Reference current is
   1 (bisection on the loss; each step a batched scan of the friction axis):
   without it the optimiser reads the missing torque at speed as extra friction.
2. ``eccentricity_gain`` c of ``Z = c zeta``: for each zeta of a grid over
   [0, 0.8] the Z that best reproduces the Reference current (batched scan,
   then a bounded scalar search), then least squares through the origin, r^2.
3. ``signature_error`` per fault at the paper's Fig. 10 levels (docs/reference.md, The models).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

from .. import signals
from ..config.parameters import Parameters
from ..config.scenario import ChirpCommand, NoLoad
from ..faults import HEALTHY, ZETA_COLUMN, MonitorFaults, monitor_form, values_of
from ..identification.objective import STARTUP_SECONDS, filter_width, low_pass
from ..models import monitor, reference
from ..models.bldc import MonitorOptions
from ..models.common import Inputs
from ..models.family import family_of
from ..numerics import DEFAULT

ZETA_GRID = np.linspace(0.1, 0.8, 8)
#: The paper's Fig. 10 levels, one fault at a time (physical form: eccentricity as zeta).
SIGNATURE_FAULTS = {
    "friction": HEALTHY._replace(friction=1.8),
    "backlash": HEALTHY._replace(backlash=4e-4),
    "short_circuit_a": HEALTHY._replace(short_a=0.2),
    "short_circuit_b": HEALTHY._replace(short_b=0.2),
    "short_circuit_c": HEALTHY._replace(short_c=0.2),
    "eccentricity": HEALTHY._replace(eccentricity_zeta=0.2),
}
#: The healthy Monitor (Z = 0).
MONITOR_HEALTHY = MonitorFaults(*HEALTHY)


def calibration_inputs(params: Parameters) -> Inputs:
    """The paper's 0.5 s chirp (0.05 rad, 0.5 -> 10 Hz), no load."""
    t = signals.time_grid(0.5, params.spec.controller.rate)
    cmd = signals.command(
        ChirpCommand(kind="chirp", amplitude=0.05, start_frequency=0.5, end_frequency=10.0), t, 0.5
    )
    torque, stiffness = signals.load(NoLoad(kind="none"), t)
    return Inputs(t, cmd, torque, stiffness)


class Fit:
    """Batched current error of Monitor fault rows against one Reference run."""

    def __init__(self, params: Parameters, inp: Inputs, reference_current: np.ndarray):
        self.params, self.inp = params, inp
        rate = params.spec.controller.rate
        width = filter_width(rate)
        current = low_pass(reference_current, width)
        sample_weight = np.ones_like(current)
        sample_weight[: round(STARTUP_SECONDS * rate)] = 0.0
        zeros = np.zeros_like(current)
        self.target = family_of(params).error_target(
            current,
            zeros,
            zeros,
            np.array([1.0, 0.0, 0.0]),
            width,
            sample_weight,
            np.arange(current.size, dtype=np.int64),
            zeros,
        )

    def __call__(self, rows: np.ndarray, opts: MonitorOptions) -> np.ndarray:
        """Error of each (m, 7) Monitor fault row under ``opts``."""
        p = self.params
        family = family_of(p)
        out = np.empty(rows.shape[0])
        family.evaluate_population(
            np.ascontiguousarray(rows),
            family.unit_row(p.plant)[None],
            self.inp.drive(),
            p.plant,
            opts,
            self.target,
            out,
        )
        return out


def fit_commutation_loss(params: Parameters, inp: Inputs) -> float:
    ref, _ = reference.run(params, inp, HEALTHY, with_noise=False)
    fit = Fit(params, inp, ref["current"])
    opts = monitor.options(params, DEFAULT)
    friction = np.linspace(0.7, 1.5, 81)
    rows = np.tile(np.asarray(MONITOR_HEALTHY, float), (friction.size, 1))
    rows[:, 0] = friction

    def friction_bias(loss: float) -> float:
        return float(friction[np.argmin(fit(rows, opts._replace(commutation_loss=loss)))] - 1.0)

    lo, hi = 0.0, 4e-4
    for _ in range(14):
        mid = 0.5 * (lo + hi)
        if friction_bias(mid) > 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def fit_eccentricity(
    params: Parameters, inp: Inputs, opts: MonitorOptions
) -> tuple[float, float, list[float]]:
    """(c, r^2, optimal Z per zeta of :data:`ZETA_GRID`)."""
    optimal = []
    for zeta in ZETA_GRID:
        ref, _ = reference.run(
            params, inp, HEALTHY._replace(eccentricity_zeta=float(zeta)), with_noise=False
        )
        fit = Fit(params, inp, ref["current"])

        def error(z: float, fit: Fit = fit) -> float:
            row = np.asarray(MONITOR_HEALTHY._replace(eccentricity_z=z), float)[None]
            return float(fit(row, opts)[0])

        scan = np.linspace(0.0, zeta, 21)
        rows = np.tile(np.asarray(MONITOR_HEALTHY, float), (scan.size, 1))
        rows[:, ZETA_COLUMN] = scan
        start = scan[np.argmin(fit(rows, opts))]
        step = scan[1] - scan[0]
        best = minimize_scalar(
            error,
            bounds=(max(start - step, 0.0), start + step),
            method="bounded",
            options={"xatol": 1e-4},
        )
        optimal.append(float(best.x))
    z = np.array(optimal)
    c = float(np.dot(ZETA_GRID, z) / np.dot(ZETA_GRID, ZETA_GRID))
    residual = z - c * ZETA_GRID
    r_squared = float(1.0 - np.sum(residual**2) / np.sum((z - z.mean()) ** 2))
    return c, r_squared, optimal


def signature_errors(
    params: Parameters, inp: Inputs, opts: MonitorOptions, gain: float
) -> dict[str, float]:
    width = filter_width(params.spec.controller.rate)
    skip = round(STARTUP_SECONDS * params.spec.controller.rate)
    ref0, _ = reference.run(params, inp, HEALTHY, with_noise=False)
    mon0 = monitor.run(params, inp, MONITOR_HEALTHY, opts=opts)
    out = {}
    for name, faults in SIGNATURE_FAULTS.items():
        ref1, _ = reference.run(params, inp, faults, with_noise=False)
        mon1 = monitor.run(params, inp, monitor_form(values_of(faults), gain), opts=opts)
        d_ref = low_pass(ref1["current"] - ref0["current"], width)[skip:]
        d_mon = low_pass(mon1["current"] - mon0["current"], width)[skip:]
        out[name] = float(np.linalg.norm(d_mon - d_ref) / np.linalg.norm(d_ref))
    return out


def calibrate(params: Parameters) -> dict:
    """Run the three steps; returns the calibration.json content."""
    inp = calibration_inputs(params)
    loss = fit_commutation_loss(params, inp)
    opts = monitor.options(params, DEFAULT)._replace(commutation_loss=loss)
    c, r_squared, optimal = fit_eccentricity(params, inp, opts)
    return {
        "parameters": params.source_file,
        "torque_gain_scale": opts.torque_gain_scale,
        "commutation_loss": loss,
        "eccentricity_gain": c,
        "r_squared": r_squared,
        "zeta": ZETA_GRID.tolist(),
        "optimal_z": optimal,
        "signature_error": signature_errors(params, inp, opts, c),
        "short_circuit_model": params.spec.monitor.short_circuit_model,
        "eccentricity_model": params.spec.monitor.eccentricity_model,
    }


def calibrated_set(source: str | Path, result: dict, date: str) -> str:
    """The input parameter file's text with the calibrated monitor values and a change record.

    Comments and layout are kept; ``changes:`` gains one line saying what moved, from
    what, and who wrote it. The text is checked to load as a parameter set with exactly
    the calibrated values before it is returned.
    """
    from ..config.parameters import ParameterFile
    from ..config.yamlfile import parse_mapping

    text = Path(source).read_text()
    before = ParameterFile.model_validate(parse_mapping(text, source)).monitor
    moved = []
    for key, fmt in CALIBRATED:
        value = fmt.format(result[key])
        text, count = re.subn(rf"^(  {key}:).*$", rf"\g<1> {value}", text, flags=re.MULTILINE)
        if count != 1:
            raise ValueError(f"{source}: cannot find monitor.{key} to update")
        moved.append(f"{key} {getattr(before, key):g} -> {float(value):g}")
    record = (
        f'"monitor: {", ".join(moved)}, written by `emaprog calibrate` on {date} '
        f"(r^2 {result['r_squared']:.4f}; signature errors "
        f'{max(result["signature_error"].values()):.2f} at most)."'
    )
    if re.search(r"^changes:\s*\[\s*\]\s*$", text, flags=re.MULTILINE):
        text = re.sub(
            r"^changes:\s*\[\s*\]\s*$", "changes:\n  - " + record, text, flags=re.MULTILINE
        )
    elif re.search(r"^changes:\s*$", text, flags=re.MULTILINE):
        lines = text.splitlines()
        start = lines.index(next(line for line in lines if re.match(r"^changes:\s*$", line)))
        end = start + 1
        # the block's items, indented or not ("- " at the margin is YAML too)
        while end < len(lines) and (lines[end].startswith((" ", "-")) or not lines[end].strip()):
            end += 1
        item = next((line for line in lines[start + 1 : end] if line.lstrip().startswith("-")), "")
        lines.insert(
            end, (item[: len(item) - len(item.lstrip())] if item else "  ") + "- " + record
        )
        text = "\n".join(lines) + "\n"
    else:
        text = text.rstrip("\n") + "\nchanges:\n  - " + record + "\n"
    after = ParameterFile.model_validate(parse_mapping(text, source)).monitor
    for key, fmt in CALIBRATED:
        if getattr(after, key) != float(fmt.format(result[key])):
            raise ValueError(f"{source}: the calibrated set does not hold monitor.{key}")
    return text


#: The monitor values calibration writes, with their format in the YAML.
CALIBRATED = (("eccentricity_gain", "{:.4f}"), ("commutation_loss", "{:.3e}"))
