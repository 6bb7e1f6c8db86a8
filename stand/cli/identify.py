"""``stand identify RUN.csv``: Q-matrix identification of one single-motor run (seed 000 eq. 10)."""

from __future__ import annotations

import argparse
import logging
from typing import Any

from stand import IdentifyResult, identify, read_run
from stand.cli import options
from stand.ident.derivatives import METHODS
from stand.ident.identify import ESTIMATORS
from stand.ident.supply import motor_supply

LOG = logging.getLogger(__name__)


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
    parser.add_argument("--effects", default="auto", metavar="auto|none|NAME[,NAME]",
                        help="effects in the model: 'auto' (default: the data choose), 'none' "
                             "(seed 000's model), or names (coulomb_friction, "
                             "stribeck_friction, cogging, current_offset, delay, torque_ripple)")
    parser.add_argument("--estimator", choices=ESTIMATORS, default=None,
                        help="how current noise is kept from biasing Kt/J: 'iv' instrumental "
                             "variables, 'bc' bias-compensated least squares, 'ls' plain least "
                             "squares, 'auto' the better of bc and iv (default with effects)")
    options.add_motor_supply(parser)


def run(args: argparse.Namespace) -> IdentifyResult:
    result = identify(read_run(args.run, "single"), args.method, args.no_load_current,
                      args.half_width, args.effects, args.estimator,
                      motor_supply(args.motor))
    if not args.json:  # human mode: the warnings on stderr, beside the summary
        for text in result.warnings:
            LOG.warning("warning: %s", text)
    return result


def summarize(result: dict[str, Any]) -> str:
    low, high = result["Kt_over_J_ci95"]
    return (
        f"{result['source']}: Kt/J = {result['Kt_over_J']:.5g} (95 % {low:.5g} … {high:.5g}) "
        f"rad/(s²·A), D/J = {result['D_over_J']:.4g} 1/s, C/J = {result['C_over_J']:.4g} 1/s²; "
        f"fit {result['fit_percent']:.1f} %, condition number {result['condition_number']:.3g}, "
        f"{result['samples']} samples ({result['method']} method, {result['estimator']}); "
        f"effects: {', '.join(result['effects']) or 'none'}"
    )
