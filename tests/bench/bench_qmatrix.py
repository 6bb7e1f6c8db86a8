"""Throughput of the Q-matrix sums (seed 000 eq. 10) against numpy reading the same data.

Run as ``python tests/bench/bench_qmatrix.py``. For 10^7 samples of a 2-state, 1-input
problem and for a batch of 1000 runs × 2000 samples it prints

- the time numpy takes to read the arrays once (``np.sum`` of each: the memory-bandwidth
  reference),
- ``QSums.add`` from separate ẋ, x, u arrays (stacks them chunk by chunk),
- ``QSums.add_stacked`` from one array ``w = [ẋ, x, u, 1]`` (one BLAS product), against
  the time numpy takes to read ``w`` once,
- ``solve``,

and the ratio to the reference (target: within 3x). Timings are the best of 3.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable

import numpy as np

from stand.ident.qmatrix import QSums, solve

TARGET_RATIO = 3.0
REPEATS = 3


def best_of(func: Callable[[], object], repeats: int = REPEATS) -> float:
    """Shortest wall time of ``repeats`` calls, s."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        func()
        times.append(time.perf_counter() - start)
    return min(times)


def case(label: str, shape: tuple[int, ...]) -> float:
    rng = np.random.default_rng(0)
    x = rng.standard_normal((*shape, 2))
    u = rng.standard_normal((*shape, 1))
    xdot = x @ np.array([[0.0, -3.0], [1.0, -2.0]]) + u @ np.array([[0.0, 5.0]])
    w = np.concatenate([xdot, x, u, np.ones((*shape, 1))], axis=-1)
    batch = shape[:-1]
    samples = int(np.prod(shape))
    mb = (xdot.nbytes + x.nbytes + u.nbytes) / 1e6

    t_read = best_of(lambda: xdot.sum() + x.sum() + u.sum())
    t_read_w = best_of(lambda: w.sum())
    t_add = best_of(lambda: QSums.zeros(2, 1, batch).add(xdot, x, u, 1e-3))
    t_stacked = best_of(lambda: QSums.zeros(2, 1, batch).add_stacked(w, 1e-3))
    sums = QSums.zeros(2, 1, batch).add_stacked(w, 1e-3)
    t_solve = best_of(lambda: solve(sums))
    print(f"{label}: {samples:.3g} samples ({mb:.0f} MB of ẋ, x, u; w = {w.nbytes / 1e6:.0f} MB)")
    print(f"  numpy reads ẋ, x, u once    : {t_read * 1e3:8.1f} ms  ({mb / 1e3 / t_read:5.1f} GB/s)")
    print(f"  QSums.add(ẋ, x, u)          : {t_add * 1e3:8.1f} ms  "
          f"({samples / t_add / 1e6:5.0f} M samples/s)  {t_add / t_read:5.1f}x")
    print(f"  numpy reads w once          : {t_read_w * 1e3:8.1f} ms")
    print(f"  QSums.add_stacked(w)        : {t_stacked * 1e3:8.1f} ms  "
          f"({samples / t_stacked / 1e6:5.0f} M samples/s)  {t_stacked / t_read_w:5.1f}x")
    print(f"  solve                       : {t_solve * 1e3:8.1f} ms")
    return (t_stacked + t_solve) / t_read_w


def main() -> int:
    print(f"BLAS threads: OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    ratios = [case("one run", (10_000_000,)),
              case("batch of 1000 runs x 2000 samples", (1000, 2000))]
    print(f"best path (add_stacked + solve) vs reading w: "
          f"{', '.join(f'{r:.1f}x' for r in ratios)} (target <= {TARGET_RATIO:g}x)")
    return 0 if max(ratios) <= TARGET_RATIO else 1


if __name__ == "__main__":
    sys.exit(main())
