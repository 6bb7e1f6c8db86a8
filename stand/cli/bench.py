"""``stand bench diagnose``: benchmarks that print figures (issue 5's blind benchmark)."""

from __future__ import annotations

import argparse
from typing import Any

from stand.cli import options
from stand.errors import InputError

BENCHMARKS = ("diagnose",)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("benchmark", choices=BENCHMARKS, help="which benchmark")
    parser.add_argument("--cases", type=options.whole(1, 10**6), default=200,
                        help="number of blind cases")
    parser.add_argument("--seed", type=options.seed, default=1, help="seed of the drawn cases")
    parser.add_argument("--workers", type=options.whole(1, 64), default=2, help="worker processes")
    parser.add_argument("--min-snr", type=options.non_negative, default=None,
                        help="least SNR of a planted effect on HOLDOUT (default "
                        "stand.diagnosis.benchmark.MIN_EFFECT_SNR; 0 keeps every first draw)")


def run(args: argparse.Namespace) -> dict[str, Any]:
    from stand.diagnosis.benchmark import MIN_EFFECT_SNR, run_benchmark, summarize_cases, timing_case

    if args.cases < 1 or args.workers < 1:
        raise InputError(f"--cases and --workers must be >= 1, got {args.cases}, {args.workers}")
    min_snr = MIN_EFFECT_SNR if args.min_snr is None else args.min_snr
    if not min_snr >= 0:
        raise InputError(f"--min-snr must be >= 0, got {args.min_snr}")
    rows = run_benchmark(args.cases, args.seed, args.workers, min_snr=min_snr)
    summary = summarize_cases(rows)
    summary["seed"] = args.seed
    summary["min_snr"] = min_snr
    summary["timing_20s_1khz"] = timing_case()
    return summary


def _percent(value: float | None) -> str:
    return "n/a" if value is None else f"{100 * value:.1f} %"


def summarize(result: dict[str, Any]) -> str:
    from stand.diagnosis.benchmark import confusion_table

    timing = result["timing_20s_1khz"]
    return "\n".join([
        confusion_table(result),
        f"cases {result['cases']} (seed {result['seed']}), effects drawn until their SNR on "
        f"HOLDOUT >= {result['min_snr']:g} ({result['redrawn_cases']} cases drawn again)",
        f"top-1 accuracy {_percent(result['top1_accuracy'])} "
        f"(exact set {_percent(result['exact_accuracy'])})",
        f"false alarms on none {_percent(result['false_alarm_rate'])} of "
        f"{result['none_cases']} effect-free cases",
        f"median holdout shrink of the true effect {_percent(result['median_true_shrink'])}",
        f"diagnose 20 s at 1 kHz: {timing['seconds']:.2f} s",
    ])
