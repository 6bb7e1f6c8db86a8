"""Throughput of the Q-matrix sums (seed 000 eq. 10) against numpy reading the same data.

Run as ``python tests/bench/bench_qmatrix.py``. Prints, for 10^7 samples of a 2-state,
1-input problem (ẋ, x, u: five float64 columns, 400 MB):

- the time numpy takes to read the arrays once (``np.sum`` of each: the memory-bandwidth
  reference),
- the time of ``QSums.add`` over the same arrays (one pass, chunked), and of ``solve``,
- the same for a batch of 1000 runs × 2000 samples,

and the ratio to the reference (target: within 3x).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

import numpy as np

from stand.ident.qmatrix import QSums, solve

TARGET_RATIO = 3.0


def best_of(repeats: int, func: Callable[[], object]) -> float:
    """Shortest wall time of ``repeats`` calls, s."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        func()
        times.append(time.perf_counter() - start)
    return min(times)


def case(label: str, shape: tuple[int, ...], repeats: int = 3) -> float:
    rng = np.random.default_rng(0)
    x = rng.standard_normal((*shape, 2))
    u = rng.standard_normal((*shape, 1))
    xdot = x @ np.array([[0.0, -3.0], [1.0, -2.0]]) + 5.0 * u @ np.array([[0.0, 1.0]])
    batch = shape[:-1]
    samples = int(np.prod(shape))
    megabytes = (xdot.nbytes + x.nbytes + u.nbytes) / 1e6

    def read_once() -> float:
        return float(xdot.sum() + x.sum() + u.sum())

    def accumulate() -> QSums:
        return QSums.zeros(2, 1, batch).add(xdot, x, u, 1e-3)

    sums = accumulate()
    reference = best_of(repeats, read_once)
    t_add = best_of(repeats, accumulate)
    t_solve = best_of(repeats, lambda: solve(sums))
    ratio = (t_add + t_solve) / reference
    print(f"{label}: {samples:.3g} samples, {megabytes:.0f} MB")
    print(f"  numpy reads the arrays once : {reference * 1e3:8.1f} ms  "
          f"({megabytes / 1e3 / reference:.2f} GB/s)")
    print(f"  QSums.add (one pass)        : {t_add * 1e3:8.1f} ms  "
          f"({samples / t_add / 1e6:.0f} M samples/s)")
    print(f"  solve                       : {t_solve * 1e3:8.1f} ms")
    print(f"  ratio to the reference      : {ratio:.2f}x (target <= {TARGET_RATIO:g}x)")
    return ratio


def main() -> int:
    ratios = [case("one run", (10_000_000,)), case("batch of 1000 runs x 2000 samples", (1000, 2000))]
    return 0 if max(ratios) <= TARGET_RATIO else 1


if __name__ == "__main__":
    sys.exit(main())
