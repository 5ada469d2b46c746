"""The identification objective: genes in [0, 1] -> fault values -> Monitor error vs a trace.

Fitness (docs/reference.md, The models): ``sum_s w_s ||lp(MM_s) - lp(meas_s)||^2 / ||lp(meas_s)||^2``
over s in (current, position, speed), on the measured samples after the
start-up window, where ``lp`` is a centred 1 ms moving average applied to both
signals (it removes the Reference/real motor's switching ripple and most of the
sensor noise, which the Monitor does not model). The command (and the load,
when the trace's scenario is known) come from the trace.

Nominal-discrepancy correction (``identify.nominal_correction``): the healthy
Monitor differs from the healthy three-phase motor by a deterministic residual
(commutation dips, freewheeling currents; its size is measured in
docs/explanation/method.md), as large as the signatures of incipient faults and
partly aligned with them, so it biases the estimates. The correction subtracts that residual from the measured signals:
the optimiser then fits the Monitor's *fault-induced* change to the measured
one, which is what fault-signature fidelity (docs/reference.md, The models) guarantees. Two sources:

* ``reference`` -- the healthy Reference minus the healthy Monitor, noise-free,
  both with the parameter set in use, on the trace's own command (assumes the
  Reference Model is the unit);
* ``recording`` -- the unit's own commissioning recording minus the healthy
  Monitor (the commissioned set, the recording's fitted hinge moment): a
  measurement of the unit's residual, usable when the inspection repeats the
  commissioning recording's command on the same sample grid; otherwise the
  ``reference`` correction is applied and the report says why.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
from typing import NamedTuple

import numpy as np

from ..config.parameters import Parameters
from ..config.scenario import IdentifySettings
from ..faults import (
    CATALOGUE,
    HEALTHY,
    NUISANCES,
    QUANTITIES,
    ZETA_COLUMN,
    healthy_values,
    monitor_form,
)
from ..io.storage import Trace
from ..models import monitor, reference
from ..models.bldc import (
    U_HINGE_MOMENT,
    U_HINGE_STIFFNESS,
    U_PHASE_RESISTANCE,
    Plant,
    moving_average,
)
from ..models.common import Inputs, recorded_instants
from ..models.family import family_of
from ..numerics import DEFAULT, Numerics

FILTER_SECONDS = 1e-3  # [s] moving-average window of the error function
STARTUP_SECONDS = 0.01  # [s] left out of the error: initial transient of the loops
TWO_PI = 2.0 * math.pi
BACK_EMF_SHARE = 0.4  # [-] pair back-EMF / DC bus at the default fit speed limit
MIN_SAMPLES_SHARE = 0.2  # [-] fewer samples below the speed limit: fit them all


class Correction(NamedTuple):
    """What is subtracted from the measured signals before fitting, and where it comes from."""

    applied: str  # "reference" | "recording" | "none"
    note: str
    signals: dict[str, np.ndarray] | None  # current, position, speed
    on_grid: bool = True  # True: on the controller grid (sampled at the recorded instants)


NO_CORRECTION = Correction("none", "identify.nominal_correction is none", None)


class Gene(NamedTuple):
    quantity: str
    lower: float
    upper: float
    circular: bool


#: Operating conditions that can be estimated beside the faults: their value when not.
NUISANCE_DEFAULTS = {n.name: n.default for n in NUISANCES.values()}


def genes_of(settings: IdentifySettings) -> list[Gene]:
    """The genes to search, in :data:`~emaprog.faults.QUANTITIES` order.

    A fault's magnitudes share its ``identify.bounds``; an angle spans the circle.
    """
    genes = []
    for fault in CATALOGUE:
        if fault.name not in settings.estimate:
            continue
        lo, hi = getattr(settings.bounds, fault.name)
        for q in fault.quantities:
            if q.circular:
                genes.append(Gene(q.name, 0.0, TWO_PI, True))
            else:
                genes.append(Gene(q.name, float(lo), float(hi), False))
    for name in NUISANCE_DEFAULTS:
        if name in (settings.nuisances or ()):
            lo, hi = getattr(settings.nuisance_bounds, name)
            genes.append(Gene(name, float(lo), float(hi), False))
    return genes


def low_pass(x: np.ndarray, width: int) -> np.ndarray:
    out = np.empty_like(x)
    moving_average(np.ascontiguousarray(x, dtype=np.float64), width, out)
    return out


def filter_width(rate: float) -> int:
    """Samples of the error's moving average at ``rate`` [Hz]: :data:`FILTER_SECONDS`, at least
    one (the same window on the Monitor's grid and on a recording's)."""
    return max(1, round(FILTER_SECONDS * rate))


def filter_lag(width: int, rate: float) -> float:
    """How far before its sample the centred ``width``-sample moving average is centred [s]."""
    return 0.5 / rate if width % 2 == 0 else 0.0


def fit_speed_limit(settings: IdentifySettings, params: Parameters) -> float:
    """Motor speed above which samples are left out of the error [rad/s].

    ``identify.max_speed`` when given; else the speed at which the active pair's
    back-EMF reaches :data:`BACK_EMF_SHARE` of the DC bus. Near the bus limit
    the incoming phase's current rise (limited by ``Vdc - 2E``) stretches the
    commutations over much of a sector, and the Monitor's averaged-duty
    commutation model (:func:`~emaprog.kernels.monitor.commutation_step`) is
    least faithful there. Measured on the 50-case quick campaign: with the
    samples above 360 rad/s left out, zeta within tolerance in 80 % of cases
    instead of 68 %, no false alarm where a fault is absent (friction 11 %,
    short circuit 10 % with every sample), other quantities unchanged within
    a few cases.
    """
    if settings.max_speed is not None:
        return float(settings.max_speed)
    e = params.spec.electrical
    return BACK_EMF_SHARE * e.dc_bus_voltage / (2.0 * e.back_emf_constant)


def sample_weights(speed: np.ndarray, limit: float, first_sample: int) -> np.ndarray:
    """1 where the (low-passed) measured motor speed is within ``limit``, else 0 [-].

    The start-up window is left out too. If fewer than :data:`MIN_SAMPLES_SHARE`
    of the samples remain, every sample after the start-up counts (a fast
    trace is still fitted, with the Monitor's commutation gap in it).
    """
    weight = (np.abs(speed) <= limit).astype(np.float64)
    weight[:first_sample] = 0.0
    if weight.sum() < MIN_SAMPLES_SHARE * speed.size:
        weight[first_sample:] = 1.0
    return weight


class Objective:
    """Batch fitness of gene rows against one measured trace (callable)."""

    def __init__(
        self,
        trace: Trace,
        inputs: Inputs,
        params: Parameters,
        settings: IdentifySettings,
        numerics: Numerics = DEFAULT,
        correction: Correction = NO_CORRECTION,
    ):
        self.params = params
        self.inputs = inputs
        self.numerics = numerics
        self.genes = genes_of(settings)
        self.options = monitor.options(params, numerics)
        self.family = family_of(params)
        self.units = self.family.unit_row(params.plant)[None]
        self.eccentricity_gain = params.spec.monitor.eccentricity_gain
        # the same 1 ms filter on both grids: the Monitor's (controller rate), the recording's
        self.filter_width = filter_width(params.spec.controller.rate)
        recording_rate = trace.sample_rate
        self.measured_width = filter_width(recording_rate)
        # A moving average over an even number of samples is centred half a sample early:
        # read the Monitor where its filtered value stands for the same instant as the
        # measurement's (no shift when both grids are the same).
        shift = filter_lag(self.filter_width, params.spec.controller.rate) - filter_lag(
            self.measured_width, recording_rate
        )
        self.instants = recorded_instants(trace.time, inputs.time, shift)
        n = trace.time.size
        self.correction = correction

        def corrected(name: str) -> np.ndarray:
            if correction.signals is None:
                return trace[name]
            signal = correction.signals[name]
            return trace[name] - (self.instants.sample(signal) if correction.on_grid else signal)

        current, position, speed = (
            low_pass(corrected(name), self.measured_width)
            for name in ("current", "position", "speed")
        )
        self.speed_limit = fit_speed_limit(settings, params)
        sample_weight = sample_weights(
            low_pass(trace["speed"], self.measured_width),
            self.speed_limit,
            min(round(STARTUP_SECONDS * recording_rate), n // 10),
        )
        w = settings.signals
        self.target = self.family.error_target(
            current,
            position,
            speed,
            np.array([w.current, w.position, w.speed], dtype=np.float64),
            self.filter_width,
            sample_weight,
            self.instants.index,
            self.instants.fraction,
        )
        self.lower = np.array([g.lower for g in self.genes])
        self.span = np.array([g.upper - g.lower for g in self.genes])
        self.circular = np.array([g.circular for g in self.genes])
        self.evaluations = 0

    @property
    def dims(self) -> int:
        return len(self.genes)

    def reweighted(self, weights: tuple[float, float, float]) -> Objective:
        """The same objective with other weights of the current, position and speed errors
        (the same recording, correction, centres and norms; its own evaluation count)."""
        other = copy.copy(self)
        other.target = self.target._replace(weights=np.array(weights, dtype=np.float64))
        other.evaluations = 0
        return other

    def values(self, genes: np.ndarray) -> dict[str, float]:
        """All fault quantities and nuisances of one gene row (healthy / default where not
        estimated)."""
        out = {**healthy_values(), **NUISANCE_DEFAULTS}
        for gene, x in zip(self.genes, np.asarray(genes, float)):
            if gene.circular:
                out[gene.quantity] = float((x % 1.0) * TWO_PI)
            else:
                out[gene.quantity] = float(
                    gene.lower + min(max(x, 0.0), 1.0) * (gene.upper - gene.lower)
                )
        return out

    def genes_for(self, values: dict[str, float]) -> np.ndarray:
        """Inverse of :meth:`values` (clipped into the bounds)."""
        values = {**NUISANCE_DEFAULTS, **values}
        return np.array(
            [
                (values[g.quantity] / TWO_PI) % 1.0
                if g.circular
                else min(max((values[g.quantity] - g.lower) / (g.upper - g.lower), 0.0), 1.0)
                for g in self.genes
            ]
        )

    def kernel_rows(self, genes: np.ndarray) -> np.ndarray:
        """(m, 7) Monitor fault rows (:class:`~emaprog.faults.MonitorFaults` order, Z = c zeta)."""
        genes = np.atleast_2d(genes)
        rows = np.tile(np.asarray(HEALTHY, float), (genes.shape[0], 1))
        index = {name: k for k, name in enumerate(QUANTITIES)}
        for j, gene in enumerate(self.genes):
            if gene.quantity in NUISANCE_DEFAULTS:
                continue
            col = genes[:, j]
            k = index[gene.quantity]
            rows[:, k] = (
                (col % 1.0) * TWO_PI
                if gene.circular
                else self.lower[j] + np.clip(col, 0, 1) * self.span[j]
            )
        rows[:, ZETA_COLUMN] *= self.eccentricity_gain
        return np.ascontiguousarray(rows)

    def unit_rows(self, genes: np.ndarray) -> np.ndarray:
        """(m, 11) unit rows: the set's plant with each candidate's nuisances, or (1, 11)."""
        genes = np.atleast_2d(genes)
        nuisances = [(j, g) for j, g in enumerate(self.genes) if g.quantity in NUISANCE_DEFAULTS]
        if not nuisances:
            return self.units
        units = np.tile(self.units[0], (genes.shape[0], 1))
        for j, gene in nuisances:
            value = self.lower[j] + np.clip(genes[:, j], 0, 1) * self.span[j]
            if gene.quantity == "hinge_moment":
                units[:, U_HINGE_MOMENT] = value
            elif gene.quantity == "hinge_stiffness":
                units[:, U_HINGE_STIFFNESS] = value
            else:
                units[:, U_PHASE_RESISTANCE] = self.units[0, U_PHASE_RESISTANCE] * value
        return units

    def __call__(self, genes: np.ndarray) -> np.ndarray:
        rows = self.kernel_rows(genes)
        fitness = np.empty(rows.shape[0])
        self.family.evaluate_population(
            rows,
            self.unit_rows(genes),
            self.inputs.drive(),
            self.params.plant,
            self.options,
            self.target,
            fitness,
        )
        self.evaluations += rows.shape[0]
        return fitness

    def residuals(self, genes: np.ndarray, plant: Plant | None = None) -> np.ndarray:
        """(m, N) weighted residual vectors of gene rows (one batch; the squared sum of a row
        is its fitness), over the samples and signals the fitness uses; ``plant`` replaces
        the set's (e.g. unquantised feedback for finite differences)."""
        rows = self.kernel_rows(genes)
        out = np.empty((rows.shape[0], 3, self.target.current.size))
        self.family.evaluate_residuals(
            rows,
            self.unit_rows(genes),
            self.inputs.drive(),
            plant if plant is not None else self.params.plant,
            self.options,
            self.target,
            out,
        )
        self.evaluations += rows.shape[0]
        used = (self.target.weights[:, None] > 0.0) & (self.target.sample_weight[None, :] > 0.0)
        return out[:, used]

    def healthy_genes(self) -> np.ndarray:
        return self.genes_for(healthy_values())

    def simulate(
        self, values: dict[str, float], plant: Plant | None = None
    ) -> dict[str, np.ndarray]:
        """Monitor columns for one set of fault (and nuisance) values, not clipped to the
        search bounds; ``plant`` replaces the set's (its unit values still apply)."""
        values = {**healthy_values(), **NUISANCE_DEFAULTS, **values}
        unit = self.units[0].copy()
        unit[U_HINGE_MOMENT] = values["hinge_moment"]
        unit[U_PHASE_RESISTANCE] *= values["resistance_factor"]
        spring = self.inputs.load_stiffness + values["hinge_stiffness"]
        return monitor.run(
            self.params,
            self.inputs._replace(load_stiffness=spring),
            monitor_form(values, self.eccentricity_gain),
            opts=self.options,
            hinge_moment=float(unit[U_HINGE_MOMENT]),
            plant=self.family.unit_plant(plant if plant is not None else self.params.plant, unit),
        )


SIGNALS = ("current", "position", "speed")

#: [-] ADC steps of the fed-back signals in a Monitor differentiated by finite differences, as
#: a share of the real ones. With the real ADC the loop acts on quantised position and
#: speed, which makes the residual a staircase in the parameters: finite differences below
#: 1e-3 then measure its jumps (commissioning measured slopes 40-100x too large). Without it
#: the slopes agree from 1e-5 to 1e-3; the quantisation itself (6e-5 rad, 0.12 rad/s at
#: 14 bit) is far below what the faults and unit parameters change.
FINE_QUANTISATION = 1e-9


def fine_plant(plant: Plant) -> Plant:
    """``plant`` with its ADC steps shrunk by :data:`FINE_QUANTISATION` (smooth residuals)."""
    s = plant.sensors
    return plant._replace(
        sensors=s._replace(
            position_lsb=s.position_lsb * FINE_QUANTISATION,
            speed_lsb=s.speed_lsb * FINE_QUANTISATION,
            current_lsb=s.current_lsb * FINE_QUANTISATION,
            angle_lsb=s.angle_lsb * FINE_QUANTISATION,
        )
    )


class DiscrepancyCache:
    """Nominal discrepancies already computed in this process, by set, inputs and numerics:
    the cases of a campaign on one set and one command share theirs (a Reference run each).
    At most ``kept`` entries (the oldest goes first), read-only arrays; :meth:`clear` empties
    it (tests, long-lived services)."""

    def __init__(self, kept: int = 8):
        self.kept = kept
        self._found: dict[str, dict[str, np.ndarray]] = {}

    def get(self, key: str, compute) -> dict[str, np.ndarray]:
        """The entry under ``key``, made by ``compute()`` the first time."""
        if key not in self._found:
            found = compute()
            for array in found.values():
                array.setflags(write=False)
            if len(self._found) >= self.kept:
                self._found.pop(next(iter(self._found)))
            self._found[key] = found
        return self._found[key]

    def clear(self) -> None:
        self._found.clear()


#: The process's cache of nominal discrepancies (:func:`nominal_discrepancy`).
DISCREPANCIES = DiscrepancyCache()


def _discrepancy_key(inputs: Inputs, params: Parameters, numerics: Numerics) -> str:
    digest = hashlib.sha256(json.dumps(params.values(), sort_keys=True).encode())
    for array in (inputs.time, inputs.command, inputs.load_torque):
        digest.update(np.ascontiguousarray(array, float).tobytes())
    digest.update(repr((float(inputs.load_stiffness), tuple(numerics))).encode())
    return digest.hexdigest()


def nominal_discrepancy(
    inputs: Inputs, params: Parameters, numerics: Numerics = DEFAULT
) -> dict[str, np.ndarray]:
    """Healthy Reference minus healthy Monitor, noise-free, on the same inputs (controller grid).

    Kept per process (read-only arrays) for the next identification with the same set,
    inputs and numerics.
    """

    def compute() -> dict[str, np.ndarray]:
        ref, _ = reference.run(params, inputs, HEALTHY, with_noise=False, numerics=numerics)
        mon = monitor.run(params, inputs, monitor_form(healthy_values(), 1.0), numerics)
        return {name: ref[name] - mon[name] for name in SIGNALS}

    return DISCREPANCIES.get(_discrepancy_key(inputs, params, numerics), compute)


def reference_correction(
    inputs: Inputs, params: Parameters, numerics: Numerics = DEFAULT, note: str = ""
) -> Correction:
    """The ``reference`` correction (see the module's docstring)."""
    return Correction(
        "reference",
        note
        or "healthy Reference minus healthy Monitor with the "
        "parameter set in use, on the trace's own command",
        nominal_discrepancy(inputs, params, numerics),
    )


class ResidualRecording(NamedTuple):
    """A commissioning recording's residual: recording minus healthy Monitor, at its samples."""

    source: str
    time: np.ndarray  # [s] from the recording's first sample
    command: np.ndarray  # [rad]
    residual: dict[str, np.ndarray]


def recording_residual(
    recording: Trace,
    rec_inputs: Inputs,
    params: Parameters,
    hinge_moment: float,
    source: str,
    numerics: Numerics = DEFAULT,
    hinge_stiffness: float = 0.0,
) -> ResidualRecording:
    """The healthy recording minus the healthy Monitor of ``params`` under its hinge moment
    [N m] and aerodynamic spring [N m/rad] (the commissioning's)."""
    spring_inputs = rec_inputs._replace(load_stiffness=rec_inputs.load_stiffness + hinge_stiffness)
    mon = monitor.run(
        params,
        spring_inputs,
        monitor_form(healthy_values(), 1.0),
        numerics,
        hinge_moment=hinge_moment,
    )
    at = recorded_instants(recording.time, rec_inputs.time)
    return ResidualRecording(
        source,
        recording.time - recording.time[0],
        np.asarray(recording["command"], float),
        {name: recording[name] - at.sample(mon[name]) for name in SIGNALS},
    )


#: [-] largest command difference, over the command's RMS, for which an inspection repeats
#: the commissioning recording's command (rig commands are programmed: equal to rounding)
SAME_COMMAND = 1e-3


def recording_correction(trace: Trace, recording: ResidualRecording) -> Correction | str:
    """The ``recording`` correction for ``trace``, or why it does not apply."""
    time = trace.time - trace.time[0]
    if time.size != recording.time.size or not np.allclose(
        time, recording.time, rtol=0.0, atol=1e-3 / trace.sample_rate
    ):
        return (
            f"the commissioning recording {recording.source} has another sample grid "
            f"({recording.time.size} samples, the trace {time.size})"
        )
    command = np.asarray(trace["command"], float)
    scale = max(float(np.sqrt(np.mean(command**2))), 1e-12)
    if float(np.max(np.abs(command - recording.command))) > SAME_COMMAND * scale:
        return f"the trace's command is not the commissioning recording's ({recording.source})"
    return Correction(
        "recording",
        f"residual of the commissioning recording {recording.source} "
        "(recording minus the healthy Monitor of the commissioned set)",
        recording.residual,
        on_grid=False,
    )
