"""``stand torque-constant``: Kt from no-load and added-inertia runs (seed 000 eqs. 11-17)."""

from __future__ import annotations

import argparse
from typing import Any

from stand import TorqueConstantResult, read_run, torque_constant
from stand.cli import options
from stand.ident.derivatives import METHODS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--no-load", nargs="+", required=True, metavar="RUN.csv",
                        type=options.input_file,
                        help="no-load runs (single-motor CSV), one per repeat")
    parser.add_argument("--loaded", nargs="+", required=True, metavar="RUN.csv",
                        type=options.input_file,
                        help="runs with the added inertia, paired in order with --no-load")
    parser.add_argument("--added-inertia", type=options.positive, required=True, metavar="KGM2",
                        help="inertia of the added disk, kg·m²")
    parser.add_argument("--method", choices=METHODS, default="default",
                        help="derivatives: 'default' kernel filtering, 'paper' forward Euler")
    parser.add_argument("--no-compensation", action="store_true",
                        help="do not subtract the no-load current (seed 000 §5.1)")
    parser.add_argument("--half-width", type=options.whole(1, 10**5), default=None,
                        help="half width of the default method's kernel, samples "
                             "(default: chosen from the current's noise)")


def run(args: argparse.Namespace) -> TorqueConstantResult:
    return torque_constant(
        [read_run(path, "single") for path in args.no_load],
        [read_run(path, "single") for path in args.loaded],
        args.added_inertia, args.method, not args.no_compensation, args.half_width)


def summarize(result: dict[str, Any]) -> str:
    comp = "compensated" if result["compensated"] else "not compensated"
    return (
        f"Kt = {result['Kt']:.5g} ± {result['Kt_std']:.2g} N·m/A over {result['repeats']} "
        f"repeat(s); J = {result['J']:.4g} kg·m², D = {result['D']:.3g} N·m·s/rad, "
        f"C = {result['C']:.3g} N·m/rad; no-load current {result['no_load_current_A']:.4g} A "
        f"({comp}, {result['method']} method)"
    )
