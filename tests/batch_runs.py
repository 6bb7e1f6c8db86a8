"""Run files for the batch tests: short simulated runs of shipped profiles, written as CSV."""

from __future__ import annotations

from pathlib import Path

import stand
from stand.runfile import write_run

#: Half a second at 1 kHz: long enough for the Q-matrix fit (tens of ms per item).
DURATION_S = 0.5
PERIOD_S = 1e-3
#: The bad file of a batch: a cell that is not a number.
BAD_CSV = "time_s,current_A,position_rad\n0,1,x\n"


def write_runs(folder: Path, count: int, profile: str = "crouzet_82800502",
               seed0: int = 0, duration_s: float = DURATION_S) -> list[Path]:
    """``count`` runs of ``profile`` (seeds ``seed0 ...``) as ``folder/run_NNN.csv``."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for k in range(count):
        run = stand.simulate(profile, duration_s=duration_s, period_s=PERIOD_S, seed=seed0 + k)
        paths.append(write_run(folder / f"run_{seed0 + k:03d}.csv", run.columns))
    return paths


def write_bad(path: Path) -> Path:
    """A run file that breaks CONTRACT §1 (row 2, column position_rad)."""
    path.write_text(BAD_CSV, encoding="utf-8")
    return path
