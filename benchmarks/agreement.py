"""Monitor vs Reference agreement figure (the paper's Figs. 8-10): ``docs/agreement.png``.

Noise-free runs, equivalent current low-passed by the 1 ms mean of the error
function. Panels: healthy chirp; Fig. 10 four-fault combination; a 30 % short
circuit on phase A with the modulated (default) and averaged PSC laws, and
with the modulated law but no commutation transients in the Monitor.
Run: ``python benchmarks/agreement.py``.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from emaprog.config import parameters  # noqa: E402
from emaprog.config.scenario import load_scenario  # noqa: E402
from emaprog.faults import (  # noqa: E402
    HEALTHY,
    flatten,
    monitor_form,
    reference_form,
    values_of,
)
from emaprog.identification.objective import low_pass  # noqa: E402
from emaprog.kernels.monitor import SHORT_CIRCUIT_AVERAGED  # noqa: E402
from emaprog.models import monitor, reference  # noqa: E402
from emaprog.models.common import inputs  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def nrmse(model, truth, skip=100):
    return np.sqrt(np.mean((model[skip:] - truth[skip:]) ** 2) / np.mean(truth[skip:] ** 2))


def main(path: Path = ROOT / "docs" / "agreement.png") -> Path:
    params = parameters.load("default")
    scenario = load_scenario(ROOT / "configs" / "fig10-multiple-faults.yaml")
    inp = inputs(scenario, params)
    c = params.spec.monitor.eccentricity_gain
    opts = monitor.options(params)
    averaged = opts._replace(short_circuit_model=SHORT_CIRCUIT_AVERAGED)
    psc = HEALTHY._replace(short_a=0.3)
    fig10 = flatten(scenario.faults)
    cases = [
        ("healthy", HEALTHY, opts),
        ("Fig. 10 faults", reference_form(fig10), opts),
        ("PSC A 0.3, modulated law", psc, opts),
        ("PSC A 0.3, averaged law", psc, averaged),
        (
            "PSC A 0.3, modulated law, no commutation transients",
            psc,
            opts._replace(commutation=False),
        ),
    ]
    fig, axes = plt.subplots(len(cases), 1, figsize=(10, 2.6 * len(cases)), sharex=True)
    for ax, (title, faults, mon_opts) in zip(axes, cases):
        ref, _ = reference.run(params, inp, faults, with_noise=False)
        mon = monitor.run(params, inp, monitor_form(values_of(faults), c), opts=mon_opts)
        r, m = low_pass(ref["current"], 10), low_pass(mon["current"], 10)
        ax.plot(inp.time, r, lw=0.9, label="Reference (3-phase, hysteresis)")
        ax.plot(inp.time, m, lw=0.9, ls="--", label="Monitor (single-phase)")
        ax.set_title(f"{title}: current NRMSE {100 * nrmse(m, r):.1f} %", fontsize=10)
        print(f"{title}: current NRMSE {100 * nrmse(m, r):.2f} %")
        ax.set_ylabel("I_eq [A]")
        ax.set_xlim(0.3, 0.5)
    axes[0].legend(loc="upper left")
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


if __name__ == "__main__":
    print(main())
