"""Figures a person looks at to judge a diagnosis (matplotlib, Agg backend, PNG files).

* ``speed.png``: measured and simulated speed on HOLDOUT, nominal and with the verdict:
  the whole run, or its ``SPEED_WINDOW_S`` where the nominal model errs most;
* ``residual_vs_velocity.png``: the nominal model's residual against velocity;
* ``residual_vs_position.png``: the residual against position modulo one revolution
  (modulo one cycle of its position order, when it has one);
* ``residual_spectrum.png``: the residual's power spectrum.

The scatter figures draw the residual's mean in bins over the points (the curve an
effect would follow), and every title carries the verdict and its shrink of the gap.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes

from stand.diagnosis.engine import Traces
from stand.diagnosis.report import Diagnosis
from stand.diagnosis.signals import power_spectral_density

#: Longest stretch of HOLDOUT shown in the speed figure, s.
SPEED_WINDOW_S = 3.0
#: Most points drawn in a scatter figure.
SCATTER_POINTS = 20_000
#: Bins of the averaged curve drawn over a scatter.
CURVE_BINS = 60


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


def worst_window(time_s: np.ndarray, error: np.ndarray, width_s: float) -> np.ndarray:
    """Mask of the samples in the ``width_s`` window (s) of largest summed ``error``
    (``time_s`` increasing); all samples when the run is no longer than it."""
    if time_s[-1] - time_s[0] <= width_s:
        return np.ones(len(time_s), dtype=bool)
    ends = np.searchsorted(time_s, time_s + width_s)
    total = np.concatenate([[0.0], np.cumsum(error)])
    start = int(np.argmax(total[ends] - total[:len(time_s)]))
    return np.asarray((time_s >= time_s[start]) & (time_s < time_s[start] + width_s))


def _verdict(d: Diagnosis) -> str:
    """Verdict and its shrink of the gap, for a title."""
    shrink = 1.0 - d.verdict_gap_percent / d.gap_percent if d.gap_percent > 0 else 0.0
    return f"verdict {d.verdict}, shrink {shrink:.2f}"


def _speed(ax: Axes, t: Traces, d: Diagnosis) -> None:
    time = t.time_s.reshape(-1)
    order = np.argsort(time)
    time = time[order]
    nominal_error = (t.nominal - t.measured).reshape(-1)[order] ** 2
    keep = worst_window(time, nominal_error, SPEED_WINDOW_S)
    where = ("whole run" if keep.all()
             else f"the {SPEED_WINDOW_S:g} s where the nominal model errs most")
    for values, label, color, style in (
        (t.measured, "measured", "k", "-"),
        (t.nominal, f"nominal model (gap {d.gap_percent:.2f} %)", "C3", "-"),
        (t.verdict, f"with {d.verdict} (gap {d.verdict_gap_percent:.2f} %)", "C0", "--"),
    ):
        ax.plot(time[keep], values.reshape(-1)[order][keep], label=label, color=color,
                ls=style, lw=0.9)
    ax.set_xlabel("time, s")
    ax.set_ylabel("speed, rad/s")
    ax.set_title(f"HOLDOUT speed from the measured current, {where}\n{_verdict(d)}",
                 fontsize=10)
    ax.legend(loc="best", fontsize=8)


def _thin(n: int) -> np.ndarray:
    return np.arange(0, n, max(1, n // SCATTER_POINTS))


def _curve(ax: Axes, x: np.ndarray, y: np.ndarray, color: str) -> None:
    """The mean of ``y`` in ``CURVE_BINS`` bins of ``x``, drawn over the scatter."""
    edges = np.linspace(float(np.min(x)), float(np.max(x)), CURVE_BINS + 1)
    which = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, CURVE_BINS - 1)
    count = np.bincount(which, minlength=CURVE_BINS)
    mean = np.bincount(which, weights=y, minlength=CURVE_BINS) / np.maximum(count, 1)
    centres = 0.5 * (edges[1:] + edges[:-1])
    ax.plot(centres[count > 0], mean[count > 0], color=color, lw=2.0, label="mean in bins")
    ax.legend(loc="best", fontsize=8)


def _vs_velocity(ax: Axes, t: Traces, d: Diagnosis) -> None:
    pick = _thin(len(t.omega))
    ax.plot(t.omega[pick], t.residual[pick], ".", ms=1.5, alpha=0.3, color="C0")
    _curve(ax, t.omega, t.residual, "k")
    ax.axvline(0.0, color="k", lw=0.5)
    ax.set_xlabel("velocity, rad/s")
    ax.set_ylabel("residual acceleration, rad/s²")
    ax.set_title(f"nominal residual against velocity (regime: {d.where.regime}; "
                 f"{_verdict(d)})", fontsize=10)


def _vs_position(ax: Axes, t: Traces, d: Diagnosis) -> None:
    """Against position modulo one revolution, or, when the residual has a position order
    ``N``, modulo one cycle of it (``N·θ`` modulo 2π): ``CURVE_BINS`` bins over a whole
    revolution cannot show a curve of 24 cycles, and folded on the cycle every cycle's
    points fall on one curve."""
    pick = _thin(len(t.theta))
    order = d.where.cycles_per_rev
    angle = np.mod((order or 1) * t.theta, 2 * math.pi)
    ax.plot(angle[pick], t.residual[pick], ".", ms=1.5, alpha=0.3, color="C2")
    _curve(ax, angle, t.residual, "k")
    ax.set_xlabel(f"position × {order} modulo 2π (one cycle of the order), rad" if order
                  else "position modulo one revolution, rad")
    ax.set_ylabel("residual acceleration, rad/s²")
    ax.set_title("nominal residual against position"
                 + (f" ({order} cycles/rev)" if order else "") + f" ({_verdict(d)})",
                 fontsize=10)


def _spectrum(ax: Axes, t: Traces, d: Diagnosis) -> None:
    freq, power = power_spectral_density(t.residual, t.dt_s, min(1024, len(t.residual)))
    ax.semilogy(freq[1:], power[1:], color="C1")
    if d.where.band_hz:
        ax.axvspan(*d.where.band_hz, color="C1", alpha=0.15, label="band of half the energy")
        ax.legend(loc="best", fontsize=8)
    ax.set_xlabel("frequency, Hz")
    ax.set_ylabel("power, (rad/s²)²/Hz")
    ax.set_title(f"nominal residual spectrum ({_verdict(d)})", fontsize=10)
