"""``stand step-identify RUN.csv [RUN.csv ...]``: R, L, K, J, Kf from voltage steps (seed 001).

Reads step run files (CONTRACT §1: ``time_s``, ``voltage_V``, ``velocity_rad_s``, optional
``current_A``), identifies all of them jointly with :func:`stand.stepid.identify_steps`
and returns its result as JSON (CONTRACT §2).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

from stand import InputError, Run, StepResult, read_run, step_identify
from stand.cli import options
from stand.stepid import METHODS, PARAM_NAMES, simulated_response
from stand.stepid.model import HOLDS, PARAM_UNITS


def parse_known(items: list[str]) -> dict[str, float]:
    """``["R=2.937", "K=0.6571"]`` to ``{"R": 2.937, "K": 0.6571}``."""
    known: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or name not in PARAM_NAMES:
            raise InputError(
                f"--known {item!r}: expected NAME=VALUE with NAME one of {', '.join(PARAM_NAMES)}"
            )
        try:
            number = float(value)
        except ValueError:
            raise InputError(f"--known {item!r}: {value!r} is not a number") from None
        if not (math.isfinite(number) and number > 0):
            raise InputError(f"--known {item!r}: the value must be a finite number > 0")
        known[name] = number
    return known


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("runs", nargs="+", metavar="RUN.csv", type=options.input_file,
                        help="voltage-step run files")
    parser.add_argument("--known", action="append", default=[], metavar="NAME=VALUE",
                        help=f"a known parameter ({', '.join(PARAM_NAMES)}; SI units), "
                             "repeatable; it comes back as given")
    parser.add_argument("--method", choices=METHODS, default="trf",
                        help="trust-region reflective, Levenberg-Marquardt, gradient descent, "
                             "pattern search (default trf)")
    parser.add_argument("--hold", choices=HOLDS, default="preceding",
                        help="voltage_V[k] was applied over the period ending (preceding, as "
                             "drives report it) or starting (following) at time_s[k]")
    parser.add_argument("--speed-only", action="store_true",
                        help="ignore current_A even when the runs have it")
    parser.add_argument("--plot", metavar="FILE.png", type=options.plot_file,
                        help="write measured vs simulated speed and the residual")


def plot(result: StepResult, runs: list[Run], path: str) -> Path:
    """Measured vs simulated speed (and current) and the residuals, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = 2 if result.used_current else 1
    fig, axes = plt.subplots(2, rows, figsize=(6 * rows, 6), sharex=True, squeeze=False)
    channels = [("velocity_rad_s", "speed", "rad/s")] + (
        [("current_A", "current", "A")] if result.used_current else [])
    for index, run in enumerate(runs):
        simulated = simulated_response(result, run, index)
        for col, (name, label, unit) in enumerate(channels):
            t = run.time_s - run.time_s[0]
            axes[0, col].plot(t, run[name], lw=0.6, label=f"measured {Path(run.source).name}")
            axes[0, col].plot(t, simulated[col], lw=1.2, label="model")
            axes[1, col].plot(t, run[name] - simulated[col], lw=0.5)
            axes[0, col].set_ylabel(f"{label}, {unit}")
            axes[1, col].set_ylabel(f"{label} residual, {unit}")
            axes[1, col].set_xlabel("time, s")
    num, den = result.transfer_function["num"], result.transfer_function["den"]
    axes[0, 0].set_title(f"ω/v = {num[0]:.4g} / (s² + {den[1]:.4g}·s + {den[2]:.4g}), "
                         f"fit {result.fit_percent:.2f} %", fontsize=9)
    for ax in axes[0]:
        ax.legend(fontsize=7)
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def run(args: argparse.Namespace) -> StepResult:
    known = parse_known(args.known)
    runs = [read_run(path, "step") for path in args.runs]
    result = step_identify(runs, known=known, method=args.method, hold=args.hold,
                           use_current=not args.speed_only)
    if args.plot:
        result = replace(result, plot=str(plot(result, runs, args.plot)))
    return result


def summarize(result: dict[str, Any]) -> str:
    num, den = result["transfer_function"]["num"], result["transfer_function"]["den"]
    lines = [
        f"ω(s)/v(s) = {num[0]:.5g} / (s² + {den[1]:.5g}·s + {den[2]:.5g})   "
        f"({result['method']}, {result['runs']} run(s), {result['samples']} samples, "
        f"{'speed and current' if result['used_current'] else 'speed only'})",
        f"fit {result['fit_percent']:.2f} %" + (
            f", current fit {result['fit_percent_current']:.2f} %"
            if result["fit_percent_current"] is not None else ""),
    ]
    for name in PARAM_NAMES:
        value, std = result["params"][name], result["std"][name]
        unit = PARAM_UNITS[name]
        if value is None:
            lines.append(f"  {name:2s} = not identifiable from these data")
        elif name in result["known"]:
            lines.append(f"  {name:2s} = {value:.6g} {unit} (given)")
        else:
            low, high = result["interval95"][name]
            lines.append(f"  {name:2s} = {value:.6g} {unit} ± {std:.2g} "
                         f"(95 %: {low:.6g} .. {high:.6g})")
    for name, test in result["whiteness"].items():
        lines.append(
            f"residual whiteness ({name}): {'pass' if test['passed'] else 'FAIL'}, "
            f"{test['outside']} of {test['lags']} lags outside the 99 % band "
            f"±{test['band']:.3g} (max |r| {test['max_abs_autocorrelation']:.3g})"
        )
    if result["message"]:
        lines.append(result["message"])
    if result.get("plot"):
        lines.append(f"plot: {result['plot']}")
    return "\n".join(lines)
