"""``stand identify RUN.csv``: Q-matrix identification of one single-motor run (seed 000 eq. 10)."""

from __future__ import annotations

import argparse
from typing import Any

from stand import IdentifyResult, identify, read_run
from stand.cli import options
from stand.ident.derivatives import METHODS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run", type=options.input_file,
                        help="single-motor run file (CSV, CONTRACT §1)")
    parser.add_argument("--method", choices=METHODS, default="default",
                        help="derivatives: 'default' kernel filtering, 'paper' forward Euler "
                             "(seed 000 §4.1)")
    parser.add_argument("--no-load-current", type=options.non_negative, default=0.0, metavar="A",
                        help="no-load current subtracted from the measured current (§5.1), A")
    parser.add_argument("--half-width", type=options.whole(1, 10**5), default=None,
                        help="half width of the default method's kernel, samples "
                             "(default: chosen from the current's noise)")


def run(args: argparse.Namespace) -> IdentifyResult:
    return identify(read_run(args.run, "single"), args.method, args.no_load_current,
                    args.half_width)


def summarize(result: dict[str, Any]) -> str:
    return (
        f"{result['source']}: Kt/J = {result['Kt_over_J']:.5g} ± {result['Kt_over_J_se']:.2g} "
        f"rad/(s²·A), D/J = {result['D_over_J']:.4g} 1/s, C/J = {result['C_over_J']:.4g} 1/s²; "
        f"fit {result['fit_percent']:.1f} %, condition number {result['condition_number']:.3g}, "
        f"{result['samples']} samples ({result['method']} method)"
    )
