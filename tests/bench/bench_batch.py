"""Figures of the batch engine (README "Batches of runs", docs/results/batch.md).

Run as ``python tests/bench/bench_batch.py [scaling|diagnosis|kt] [--items N] [--cases N]``
(all by default). Timings are wall times on whatever else the machine is doing: on the
project's 2-core build machine, shared with other jobs, they vary by 2-3x.

- ``scaling``: ``identify`` over N run files (10 s at 1 kHz each, a shipped motor) and
  ``diagnose`` over N/10 TRAIN,HOLDOUT pairs, in this process (serial) and on a
  LocalCluster of 1 and 2 worker processes: cluster start, batch time, cost per item,
  speed-up; what the cost per item implies for 10⁵ runs; and whether every row equals the
  serial path's (to 1e-12).
- ``diagnosis``: the project's blind diagnosis benchmark (cases drawn by
  :mod:`tests.bench.diagnose.benchmark`) written as run files and diagnosed with
  ``run_batch("diagnose", ...)`` on 2 workers; top-1 accuracy and false alarms as
  ``tests/bench/bench_diagnose.py`` reports them.
- ``kt``: the identification benchmark's torque-constant experiment (seed 000 eqs. 11-17)
  as a fleet: N simulated motors of one type, a no-load and an added-inertia run each,
  through ``run_batch("torque-constant", ...)``, with the fleet's Kt and its spread.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import stand
from stand.batch import BatchResult, dask_client, run_batch
from stand.runfile import write_run

MOTOR = "small_ironcore_19v"
RUN_S = 10.0
PERIOD_S = 1e-3
FLEET = 1e5


def _write(folder: Path, count: int, seed0: int, **options: Any) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for k in range(count):
        run = stand.simulate(MOTOR, duration_s=RUN_S, period_s=PERIOD_S, seed=seed0 + k,
                             **options)
        write_run(folder / f"run_{seed0 + k:05d}.csv", run.columns)


def _same(a: BatchResult, b: BatchResult) -> bool:
    for x, y in zip(a.rows, b.rows, strict=True):
        for key, value in x.items():
            other = y[key]
            if key in ("seconds", "cpu_seconds"):
                continue
            if isinstance(value, float) and isinstance(other, float):
                if not math.isclose(value, other, rel_tol=1e-12, abs_tol=0.0):
                    return False
            elif value != other:
                return False
    return [f.to_json() for f in a.fleets] == [f.to_json() for f in b.fleets] or all(
        math.isclose(p.pooled["Kt_over_J"], q.pooled["Kt_over_J"], rel_tol=1e-12)
        for p, q in zip(a.fleets, b.fleets, strict=True) if p.pooled and q.pooled)


def _timed(operation: str, inputs: list[str], workers: int,
           chunk: int = 1) -> tuple[BatchResult, float]:
    """The batch and its cluster's start time, s."""
    if workers == 0:
        return run_batch(operation, inputs, workers=0), 0.0
    start = time.perf_counter()
    with dask_client(workers=workers) as client:
        started = time.perf_counter() - start
        client.run(lambda: __import__("stand.batch.operations"))  # warm the imports
        return run_batch(operation, inputs, client=client, chunk=chunk), started


def scaling(items: int) -> None:
    with tempfile.TemporaryDirectory(prefix="bench-batch-") as tmp:
        folder = Path(tmp)
        t = time.perf_counter()
        _write(folder / "runs", items, 0)
        pairs = max(2, items // 10)
        _write(folder / "train", pairs, 10_000)
        _write(folder / "holdout", pairs, 20_000)
        print(f"wrote {items} + {2 * pairs} run files of {RUN_S:g} s at {1 / PERIOD_S:g} Hz "
              f"({MOTOR}) in {time.perf_counter() - t:.1f} s")
        cases = {"identify": ([str(folder / "runs" / "*.csv")], (1, 10)),
                 "diagnose": ([f"{folder}/train/*.csv,{folder}/holdout/*.csv"], (1,))}
        print("| operation | engine | items per task | items | cluster start s | batch s "
              "| wall per item | CPU per item | speed-up | equals serial | 10⁵ items, CPU |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for operation, (inputs, chunks) in cases.items():
            serial, _ = _timed(operation, inputs, 0)
            runs = [(0, 1, serial, 0.0)] + [
                (w, c, *_timed(operation, inputs, w, c)) for w in (1, 2) for c in chunks]
            for workers, chunk, result, started in runs:
                engine = "serial" if workers == 0 else f"LocalCluster {workers}"
                cpu = result.cpu_seconds / result.items
                print(f"| {operation} | {engine} | {chunk if workers else ''} | {result.items} "
                      f"({result.errors} errors) | {started:.1f} | {result.seconds:.2f} | "
                      f"{result.seconds / result.items * 1e3:.1f} ms | {cpu * 1e3:.1f} ms | "
                      f"{serial.seconds / result.seconds:.2f} | "
                      f"{'yes' if _same(result, serial) else 'NO'} | "
                      f"{cpu * FLEET / 3600:.2f} core-h |")


def diagnosis(cases: int, seed: int = 1) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the harness is in tests/
    from tests.bench.diagnose.benchmark import draw_case, simulate_case, summarize_cases

    with tempfile.TemporaryDirectory(prefix="bench-batch-diag-") as tmp:
        folder = Path(tmp)
        t = time.perf_counter()
        drawn = []
        for index in range(cases):
            case = draw_case(index, seed)
            for k, name in enumerate(("train", "holdout")):
                write_run(folder / f"case_{index:05d}_{name}.csv", simulate_case(case, k))
            drawn.append(case)
        print(f"drew and wrote {cases} cases (seed {seed}) in {time.perf_counter() - t:.1f} s")
        result = run_batch("diagnose", [f"{folder}/*_train.csv,{folder}/*_holdout.csv"],
                           workers=2)
    rows = []
    for case, row in zip(drawn, result.rows, strict=True):
        verdict = row["verdict"] if not row["error"] else "error"
        predicted = verdict.split("+")
        effects = {e["effect"]: e for e in __import__("json").loads(row["effects"] or "[]")}
        shrinks = [effects[t]["shrink"] for t in case.truth if t in effects]
        rows.append({"truth": case.truth, "verdict": verdict, "top1": predicted[0] in case.truth,
                     "exact": sorted(predicted) == sorted(case.truth),
                     "true_shrink": max(shrinks) if shrinks else None, "seconds": row["seconds"],
                     "snr": case.snr, "draws": case.draws})
    summary = summarize_cases(rows)
    print(f"diagnose {result.items} cases on {result.engine}: {result.seconds:.1f} s "
          f"({result.seconds / result.items:.2f} s/case wall, median "
          f"{summary['median_seconds']:.2f} s/case in a worker), {result.errors} refused")
    print(f"top-1 accuracy {100 * summary['top1_accuracy']:.1f} %, exact set "
          f"{100 * summary['exact_accuracy']:.1f} %, false alarms on none "
          f"{100 * (summary['false_alarm_rate'] or 0):.1f} % of {summary['none_cases']}")


def kt_fleet(motors: int) -> None:
    from stand.procedures import SEED_ADDED_INERTIA_KGM2

    profile = stand.load_motor(MOTOR)
    with tempfile.TemporaryDirectory(prefix="bench-batch-kt-") as tmp:
        folder = Path(tmp)
        _write(folder / "free", motors, 0)
        _write(folder / "loaded", motors, 50_000, added_inertia=SEED_ADDED_INERTIA_KGM2)
        result = run_batch("torque-constant", [f"{folder}/free/*.csv,{folder}/loaded/*.csv"],
                           {"added_inertia": SEED_ADDED_INERTIA_KGM2}, workers=2, pool="all")
    fleet = result.fleets[0]
    kt = profile.motor.Kt
    print(f"torque constant of {fleet.runs} simulated {MOTOR} (Kt {kt} N·m/A), "
          f"{result.errors} refused, {result.seconds:.1f} s on {result.engine}:")
    print(f"fleet Kt {fleet.mean:.5g} N·m/A ({100 * fleet.mean / kt:.1f} % of the profile's), "
          f"95 % {fleet.mean_ci95[0]:.5g} .. {fleet.mean_ci95[1]:.5g}; spread {fleet.std:.3g} "
          f"(95 % {fleet.std_ci95[0]:.3g} .. {fleet.std_ci95[1]:.3g}) N·m/A")


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("sections", nargs="*", default=["scaling", "diagnosis", "kt"])
    parser.add_argument("--items", type=int, default=200, help="identify items of scaling")
    parser.add_argument("--cases", type=int, default=40, help="diagnosis cases")
    parser.add_argument("--motors", type=int, default=20, help="motors of the kt fleet")
    args = parser.parse_args(argv)
    for name in args.sections:
        print(f"## {name}")
        {"scaling": lambda: scaling(args.items), "diagnosis": lambda: diagnosis(args.cases),
         "kt": lambda: kt_fleet(args.motors)}[name]()
    return 0


if __name__ == "__main__":  # the LocalCluster's processes re-import this file: guard it
    sys.exit(main(sys.argv[1:]))
