"""``stand bench diagnose``: benchmarks that print figures (issue 5's blind benchmark)."""

from __future__ import annotations

import argparse
from typing import Any

from stand.errors import InputError

BENCHMARKS = ("diagnose",)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("benchmark", choices=BENCHMARKS, help="which benchmark")
    parser.add_argument("--cases", type=int, default=200, help="number of blind cases")
    parser.add_argument("--seed", type=int, default=1, help="seed of the drawn cases")
    parser.add_argument("--workers", type=int, default=2, help="worker processes")


def run(args: argparse.Namespace) -> dict[str, Any]:
    from stand.diagnose.benchmark import run_benchmark, summarize_cases, timing_case

    if args.cases < 1 or args.workers < 1:
        raise InputError(f"--cases and --workers must be >= 1, got {args.cases}, {args.workers}")
    rows = run_benchmark(args.cases, args.seed, args.workers)
    summary = summarize_cases(rows)
    summary["seed"] = args.seed
    summary["timing_20s_1khz"] = timing_case()
    return summary


def _percent(value: float | None) -> str:
    return "n/a" if value is None else f"{100 * value:.1f} %"


def summarize(result: dict[str, Any]) -> str:
    from stand.diagnose.benchmark import confusion_table

    timing = result["timing_20s_1khz"]
    return "\n".join([
        confusion_table(result),
        f"cases {result['cases']} (seed {result['seed']})",
        f"top-1 accuracy {_percent(result['top1_accuracy'])} "
        f"(exact set {_percent(result['exact_accuracy'])})",
        f"false alarms on none {_percent(result['false_alarm_rate'])} of "
        f"{result['none_cases']} effect-free cases",
        f"median holdout shrink of the true effect {_percent(result['median_true_shrink'])}",
        f"diagnose 20 s at 1 kHz: {timing['seconds']:.2f} s",
    ])
