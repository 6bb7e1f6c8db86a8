"""Figures of a report as PNG bytes (matplotlib, Agg): the runs an analysis used, with the
result written on the figure, and the diagnosis's candidate effects.

Every axis carries its quantity and unit; every panel with more than one line has a legend.
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from stand.mdf import unit_of
from stand.runfile import Run

#: Figure size, in, and resolution, dpi: readable in a report at 100 % zoom.
FIGSIZE_IN = (9.0, 5.0)
DPI = 100
#: Panels of a run figure: the column prefix and the quantity it shows.
PANELS = (("current", "current"), ("velocity", "speed"), ("position", "position"),
          ("voltage", "voltage"))
#: Most points drawn per line (a long run is thinned evenly).
MAX_POINTS = 5000


def _png(fig: Any) -> bytes:
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI, bbox_inches="tight")  # nothing clipped
    plt.close(fig)
    return buffer.getvalue()


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def run_figure(run: Run, title: str, result_text: str = "") -> bytes:
    """The run's columns against time, one panel per quantity (current, speed or position,
    voltage), with ``result_text`` (the analysis's answer) on the figure."""
    plt = _pyplot()
    names = [n for n in run.columns if n != "time_s"]
    panels: list[tuple[str, str, list[str]]] = []
    for prefix, label in PANELS:
        columns = [n for n in names if n.startswith(prefix)]
        if prefix == "position" and any(p == "velocity" for p, _, _ in panels):
            continue  # speed already shown; position is its integral
        if columns:
            panels.append((prefix, label, columns))
    fig, axes = plt.subplots(len(panels) or 1, 1, figsize=FIGSIZE_IN, sharex=True, squeeze=False)
    time = run.time_s
    pick = np.arange(0, len(time), max(1, len(time) // MAX_POINTS))
    for ax, (_, label, columns) in zip(axes[:, 0], panels, strict=False):
        for name in columns:
            ax.plot(time[pick], run[name][pick], lw=0.8, label=name)
        ax.set_ylabel(f"{label}, {unit_of(columns[0])}")
        ax.legend(loc="upper right", fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time, s")
    axes[0, 0].set_title(title)
    if result_text:
        fig.text(0.01, 0.005, result_text, fontsize=8, family="monospace", va="bottom")
        fig.subplots_adjust(bottom=0.16)
    return _png(fig)


def effects_figure(result: Mapping[str, Any]) -> bytes:
    """Holdout gap with each candidate effect, against the nominal gap and the verdict."""
    plt = _pyplot()
    effects: Sequence[Mapping[str, Any]] = result.get("effects", [])
    names = [str(e["effect"]) for e in effects]
    gaps = [float(e["gap_percent"]) for e in effects]
    colors = ["C2" if e.get("significant") else "C7" for e in effects]
    fig, ax = plt.subplots(figsize=FIGSIZE_IN)
    ax.barh(names, gaps, color=colors)
    nominal = float(result["gap_percent"])
    ax.axvline(nominal, color="C3", ls="--", label=f"nominal model: {nominal:.2f} %")
    ax.invert_yaxis()
    ax.set_xlabel("holdout gap with the effect added, % of speed RMS")
    ax.set_ylabel("candidate effect")
    ax.set_title(f"verdict: {result.get('verdict', '?')} (green: significant)")
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(axis="x", alpha=0.3)
    return _png(fig)
