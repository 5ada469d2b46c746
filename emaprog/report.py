"""Figures and markdown from stored results (never re-simulates)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .storage import Trace  # noqa: E402


def plot_trace(trace: Trace, path: str | Path, title: str = "") -> Path:
    """Command/position, speed and current of a trace (+ phase currents if present)."""
    c = trace.columns
    t = c["time"]
    phases = all(f"current_{x}" in c for x in "abc")
    rows = 4 if phases else 3
    fig, ax = plt.subplots(rows, 1, figsize=(10, 2.4 * rows), sharex=True)
    ax[0].plot(t, c["command"], label="command")
    ax[0].plot(t, c["position"], label="position (measured)")
    ax[0].set_ylabel("surface [rad]")
    ax[0].legend(loc="upper right")
    ax[1].plot(t, c["speed"], color="tab:green")
    ax[1].set_ylabel("motor speed [rad/s]")
    ax[2].plot(t, c["current"], color="tab:red", lw=0.8)
    ax[2].set_ylabel("equivalent current [A]")
    if phases:
        for x in "abc":
            ax[3].plot(t, c[f"current_{x}"], lw=0.7, label=f"phase {x.upper()}")
        ax[3].set_ylabel("phase currents [A]\n(period means)")
        ax[3].legend(loc="upper right")
    ax[-1].set_xlabel("time [s]")
    fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
