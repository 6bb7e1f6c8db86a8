"""``stand torque-constant``: Kt from no-load and added-inertia runs (seed 000 eqs. 11-17)."""

from __future__ import annotations

import argparse
import logging
from typing import Any

from stand import TorqueConstantResult, read_run, torque_constant
from stand.cli import options
from stand.ident.derivatives import METHODS
from stand.ident.identify import ESTIMATORS
from stand.ident.supply import motor_supply

LOG = logging.getLogger(__name__)


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
    parser.add_argument("--effects", default="auto", metavar="auto|none|NAME[,NAME]",
                        help="effects in each run's model (as for stand identify); with effects "
                             "the friction model replaces the §5.1 compensation")
    parser.add_argument("--estimator", choices=ESTIMATORS, default=None,
                        help="each run's estimator, as for stand identify (default: auto with "
                             "effects, ls without)")
    options.add_motor_supply(parser)


def run(args: argparse.Namespace) -> TorqueConstantResult:
    result = torque_constant(
        [read_run(path, "single") for path in args.no_load],
        [read_run(path, "single") for path in args.loaded],
        args.added_inertia, args.method, not args.no_compensation, args.half_width,
        args.effects, args.estimator, motor_supply(args.motor))
    if not args.json:  # human mode: the warnings on stderr, beside the summary
        for text in result.warnings:
            LOG.warning("warning: %s", text)
    return result


def summarize(result: dict[str, Any]) -> str:
    comp = "compensated" if result["compensated"] else "not compensated"
    low, high = result["Kt_ci95"]
    return (
        f"Kt = {result['Kt']:.5g} N·m/A (95 % {low:.5g} … {high:.5g}; std of a pair "
        f"{result['Kt_std']:.2g}) over {result['repeats']} "
        f"repeat(s); J = {result['J']:.4g} kg·m², D = {result['D']:.3g} N·m·s/rad, "
        f"C = {result['C']:.3g} N·m/rad; no-load current {result['no_load_current_A']:.4g} A "
        f"({comp}, {result['method']} method)"
    )
