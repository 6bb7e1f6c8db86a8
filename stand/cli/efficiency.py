"""``stand efficiency RUN.csv``: reducer efficiency from a two-motor run (seed 000 eq. 18)."""

from __future__ import annotations

import argparse
import logging
from typing import Any

from stand import EfficiencyResult, efficiency, read_run
from stand.cli import options

LOG = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run", type=options.input_file,
                        help="two-motor reducer run file (CSV, CONTRACT §1)")
    parser.add_argument("--ratio", type=options.positive, required=True, metavar="N",
                        help="reduction ratio n = ω_in/ω_out")
    parser.add_argument("--k-in", type=options.positive, required=True, metavar="NM_PER_A",
                        help="torque constant of the input motor, N·m/A")
    parser.add_argument("--k-out", type=options.positive, required=True, metavar="NM_PER_A",
                        help="torque constant of the output motor, N·m/A")


def run(args: argparse.Namespace) -> EfficiencyResult:
    result = efficiency(read_run(args.run, "reducer"), args.ratio, args.k_in, args.k_out)
    if not args.json:  # human mode: the warnings on stderr, beside the summary
        for text in result.warnings:
            LOG.warning("warning: %s", text)
    return result


def summarize(result: dict[str, Any]) -> str:
    return (
        f"{result['source']}: efficiency {result['efficiency']:.4f} ± "
        f"{result['efficiency_std']:.4f} from {result['steps']} load step(s); "
        f"Δi_in = {result['delta_i_in_A']:.4g} A, Δi_out = {result['delta_i_out_A']:.4g} A"
    )
