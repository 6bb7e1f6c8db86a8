"""Blind benchmark of ``stand diagnose``. A script, not collected by pytest.

    python tests/bench/bench_diagnose.py --cases 200 --seed 1 --workers 2

Draws random stands (motor, drive mode, excitation, sensors, zero/one/two effects),
simulates TRAIN and HOLDOUT runs, diagnoses them blind from the CSV files, and prints
the confusion matrix, top-1 accuracy, false alarms on effect-free cases, the median
holdout shrink of the true effect, and the time to diagnose 20 s of 1 kHz data.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

# the harness lives in the checkout's tests package, beside (not in) the product
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.bench.diagnose.benchmark import (  # noqa: E402
    CLASSES,
    MIN_EFFECT_SNR,
    OUTSIDE_SETS,
    confusion_table,
    rescore,
    run_benchmark,
    summarize_cases,
    timing_case,
)


def _percent(value: float | None) -> str:
    return "n/a" if value is None else f"{100 * value:.1f} %"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=200)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--min-snr", type=float, default=MIN_EFFECT_SNR,
                        help="least SNR of a planted effect on HOLDOUT (weaker draws are drawn "
                        "again; 0 keeps every first draw, effects below the noise included)")
    parser.add_argument("--outside-share", type=float, default=0.0,
                        help="share of cases with one effect outside the vocabulary instead")
    parser.add_argument("--outside-set", choices=tuple(OUTSIDE_SETS), default="tuning",
                        help="which outside effects: those looked at in the design of the "
                        "rule, the set held out of all tuning, or one of the sets written "
                        "after every rule, unseen to unseen_9 (tests/bench/diagnose/outside.py)")
    parser.add_argument("--first", type=int, default=0, help="index of the first case")
    parser.add_argument("--classes", nargs="+", choices=CLASSES,
                        help="run only the cases of these classes among the --cases drawn "
                        "(same case numbers as a full run)")
    parser.add_argument("--tell-limit", action="store_true",
                        help="tell the diagnosis each drive's supply and current limit, as a "
                        "motor profile does (stand diagnose --motor)")
    parser.add_argument("--current-mean", action="store_true",
                        help="the drives also report their current averaged over each "
                        "sample period (column current_mean_A), as the diagnosis then "
                        "takes it")
    parser.add_argument("--until-shown", action=argparse.BooleanOptionalAction, default=True,
                        help="draw an outside effect, and each effect of a pair, again until "
                        "it also shows against the case's twin runs without it "
                        "(oracle.visible_against_twin; the draw since stop 67); "
                        "--no-until-shown: by the SNR alone, as the seeds before 316 were drawn")
    parser.add_argument("--no-timing", action="store_true", help="skip the timing case")
    parser.add_argument("--rows", help="write every case as JSON lines to this file, each "
                        "as soon as it is in")
    parser.add_argument("--summarize", nargs="+", metavar="ROWS",
                        help="run nothing: print the figures of the cases in these --rows files")
    parser.add_argument("--rescore", action="store_true",
                        help="with --summarize: decide each row's unexplained again by the "
                        "current rule (tests.bench.diagnose.benchmark.rescore)")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    if args.summarize:
        rows = [json.loads(line) for path in args.summarize
                for line in Path(path).read_text(encoding="utf-8").splitlines() if line]
        if args.rescore:
            rows = [rescore(row) for row in rows]
        args.no_timing = True
    else:
        out = open(args.rows, "w", encoding="utf-8") if args.rows else None  # noqa: SIM115

        def keep(row: dict[str, Any]) -> None:
            if out:
                out.write(json.dumps(row) + "\n")
                out.flush()

        rows = run_benchmark(args.cases, args.seed, args.workers, min_snr=args.min_snr,
                             outside_share=args.outside_share, first=args.first,
                             outside_set=args.outside_set, on_row=keep,
                             classes=tuple(args.classes) if args.classes else None,
                             tell_limit=args.tell_limit, current_mean=args.current_mean,
                             until_shown=args.until_shown)
        if out:
            out.close()
    wall = time.perf_counter() - start
    summary = summarize_cases(rows)
    timing = None if args.no_timing else timing_case()
    print(confusion_table(summary))
    if args.summarize:
        print(f"cases {summary['cases']} (rows of {', '.join(args.summarize)})")
    else:
        print(f"cases {summary['cases']} (seed {args.seed}), wall {wall:.0f} s with "
              f"{args.workers} workers")
    print(f"effects drawn until their SNR on HOLDOUT >= {args.min_snr:g} (true plant, "
          f"tests.bench.diagnose.snr): {summary['redrawn_cases']} cases drawn again; median SNR "
          f"{'n/a' if summary['median_snr'] is None else format(summary['median_snr'], '.2f')}")
    print(f"outside effects and pairs drawn until each effect shows against its twin runs: "
          f"{summary['until_shown_cases']} of {summary['cases']} cases' draws")
    if summary["refused"]:
        print(f"cases the engine refused (counted wrong): {summary['refused']}")
    print(f"top-1 accuracy {_percent(summary['top1_accuracy'])}  "
          f"(exact set {_percent(summary['exact_accuracy'])})")
    print(f"false alarms on none {_percent(summary['false_alarm_rate'])} of "
          f"{summary['none_cases']} effect-free cases; missed effects "
          f"{_percent(summary['missed_rate'])}")
    print(f"top-1 accuracy on the {summary['visible_cases']} cases whose planted effect is "
          f"visible (oracle: the exact effect model passes the engine's test against the "
          f"identified nominal model; effect-free cases included): "
          f"{_percent(summary['visible_top1_accuracy'])} -- a diagnostic, NOT the headline")
    print(f"median holdout shrink of the true effect {_percent(summary['median_true_shrink'])}")
    print(f"in-vocabulary top-1 {_percent(summary['in_vocabulary_top1'])} of "
          f"{summary['in_vocabulary_cases']}; wrongly unexplained "
          f"{_percent(summary['in_vocabulary_wrongly_unexplained'])} ("
          f"{summary['in_vocabulary_unexplained_after_exact']} after the planted effects named "
          f"exactly, {summary['in_vocabulary_unexplained_nothing_named']} with nothing named); "
          f"pairs exact "
          f"{_percent(summary['pairs_exact'])} of {summary['pair_cases']}")
    print(f"  against the truth alone (a Stribeck friction whose static excess never shows "
          f"counted wrong when called Coulomb friction; {summary['resolved_differs']} such "
          f"in-vocabulary cases): top-1 {_percent(summary['in_vocabulary_top1_strict'])}, "
          f"pairs exact {_percent(summary['pairs_exact_strict'])}")
    print(f"cases whose every planted effect shows against its twin runs without it "
          f"(same command, sensors and noise; oracle.visible_against_twin) -- a diagnostic, "
          f"NOT the headline: pairs exact {_percent(summary['pairs_shown_exact'])} of "
          f"{summary['pairs_shown']}; outside unexplained "
          f"{_percent(summary['outside_shown_unexplained'])} of {summary['outside_shown']}, "
          f"none {summary['outside_shown_none']}")
    source = "the rows given" if args.summarize else f"{args.outside_set} set"
    print(f"outside the vocabulary ({source}): unexplained "
          f"{_percent(summary['outside_unexplained'])} of "
          f"{summary['outside_cases']}, none {summary['outside_none']}; by effect "
          f"(unexplained, cases): {summary['outside_by_effect']}")
    if timing:
        print(f"diagnose {timing['duration_s']:.0f} s at {timing['rate_hz']:.0f} Hz: "
              f"{timing['seconds']:.2f} s (read + diagnose)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
