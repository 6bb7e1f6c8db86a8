"""Figures a person looks at to judge a diagnosis (matplotlib, Agg backend, PNG files).

* ``speed.png``: measured and simulated speed on HOLDOUT, nominal and with the verdict;
* ``residual_vs_velocity.png``: the nominal model's residual against velocity;
* ``residual_vs_position.png``: the residual against position modulo one revolution;
* ``residual_spectrum.png``: the residual's power spectrum.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes

from stand.diagnosis.engine import Traces
from stand.diagnosis.report import Diagnosis

#: Longest stretch of HOLDOUT shown in the speed figure, s.
SPEED_WINDOW_S = 3.0
#: Most points drawn in a scatter figure.
SCATTER_POINTS = 20_000


def write_plots(folder: str | Path, diagnosis: Diagnosis, traces: Traces) -> list[Path]:
    """Write the four PNGs of a diagnosis (from
    :func:`~stand.diagnosis.engine.diagnose_with_traces`) to ``folder``; return their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, draw in (("speed", _speed), ("residual_vs_velocity", _vs_velocity),
                       ("residual_vs_position", _vs_position),
                       ("residual_spectrum", _spectrum)):
        fig, ax = plt.subplots(figsize=(9, 4.5), dpi=100)
        draw(ax, traces, diagnosis)
        fig.tight_layout()
        path = folder / f"{name}.png"
        fig.savefig(path, bbox_inches="tight")  # no label clipped, whatever its length
        plt.close(fig)
        paths.append(path)
    return paths


def _speed(ax: Axes, t: Traces, d: Diagnosis) -> None:
    time = t.time_s.reshape(-1)
    keep = time <= time[0] + SPEED_WINDOW_S
    order = np.argsort(time[keep])
    for values, label, color, style in (
        (t.measured, "measured", "k", "-"),
        (t.nominal, f"nominal model (gap {d.gap_percent:.2f} %)", "C3", "-"),
        (t.verdict, f"with {d.verdict} (gap {d.verdict_gap_percent:.2f} %)", "C0", "--"),
    ):
        ax.plot(time[keep][order], values.reshape(-1)[keep][order], label=label, color=color,
                ls=style, lw=0.9)
    ax.set_xlabel("time, s")
    ax.set_ylabel("speed, rad/s")
    ax.set_title("HOLDOUT speed, simulated from the measured current "
                 "(re-anchored every segment)")
    ax.legend(loc="best", fontsize=8)


def _thin(n: int) -> np.ndarray:
    return np.arange(0, n, max(1, n // SCATTER_POINTS))


def _vs_velocity(ax: Axes, t: Traces, d: Diagnosis) -> None:
    pick = _thin(len(t.omega))
    ax.plot(t.omega[pick], t.residual[pick], ".", ms=1.5, alpha=0.4, color="C0")
    ax.axvline(0.0, color="k", lw=0.5)
    ax.set_xlabel("velocity, rad/s")
    ax.set_ylabel("residual acceleration, rad/s²")
    ax.set_title(f"nominal residual against velocity (regime: {d.where.regime})")


def _vs_position(ax: Axes, t: Traces, d: Diagnosis) -> None:
    pick = _thin(len(t.theta))
    angle = np.mod(t.theta[pick], 2 * math.pi)
    ax.plot(angle, t.residual[pick], ".", ms=1.5, alpha=0.4, color="C2")
    order = d.where.cycles_per_rev
    ax.set_xlabel("position modulo one revolution, rad")
    ax.set_ylabel("residual acceleration, rad/s²")
    ax.set_title("nominal residual against position"
                 + (f" ({order} cycles/rev)" if order else ""))


def _spectrum(ax: Axes, t: Traces, d: Diagnosis) -> None:
    from scipy import signal as sps

    freq, power = sps.welch(t.residual, fs=1.0 / t.dt_s, nperseg=min(1024, len(t.residual)))
    ax.semilogy(freq[1:], power[1:], color="C1")
    if d.where.band_hz:
        ax.axvspan(*d.where.band_hz, color="C1", alpha=0.15, label="band of half the energy")
        ax.legend(loc="best", fontsize=8)
    ax.set_xlabel("frequency, Hz")
    ax.set_ylabel("power, (rad/s²)²/Hz")
    ax.set_title("nominal residual spectrum")
