"""Reducer efficiency (seed 000 eq. 18) on the simulated two-motor stand, with Coulomb
friction on both shafts and an input that reverses.

The stand is ``profiles/stands/cycloidal_two_motor.yaml`` (two Crouzet 82800502 motors
around a reducer of ratio 11) with, per case, a true efficiency drawn from 0.6–0.95,
Coulomb friction on the input shaft of 2–20 % of the input motor's load torque and on
the output shaft of 2–20 % of the load, and a speed command that turns the input one way
for the first half of the run and the other way for the second. The output motor steps
its current between 0 and a load; ``--load`` chooses whether the load opposes the motion
in both halves (a brake: the gear drives it, power flows forward) or keeps one sign (in
the second half the output motor drives the gear: power flows backward). Each run goes
through a CSV file and ``efficiency`` sees only that.

Figures: the share of cases within ±0.01 of the truth, the share whose
``efficiency_ci95`` holds it, the median absolute error and the steps kept.

    python tests/bench/bench_efficiency.py --cases 20 --seed 1
    python tests/bench/bench_efficiency.py --cases 20 --seed 1 --load one-sign
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from stand.errors import StandError
from stand.ident.efficiency import efficiency
from stand.physics.effects import Effects
from stand.physics.parts import ReducerParams
from stand.physics.reducer import ReducerPlant
from stand.physics.simulate import simulate_reducer
from stand.profiles import load_motor, load_stand
from stand.runfile import read_run, write_run

STAND = "cycloidal_two_motor"
RUN_DURATION_S = 12.0
#: Load plateaus per direction (alternately unloaded and loaded, after a settling one).
PLATEAUS_PER_HALF = 7


def reversing_commands(samples: int, speed: float, load_A: float, brake: bool
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Input speed ``+speed`` then ``−speed``; output current 0 and the load alternately,
    each half starting unloaded. ``brake``: the load opposes the motion in both halves."""
    half = samples // 2
    direction = np.where(np.arange(samples) < half, 1.0, -1.0)
    within = np.arange(samples) % half * PLATEAUS_PER_HALF // half
    loaded = within % 2 == 1
    sign = -direction if brake else -np.ones(samples)
    return speed * direction, np.where(loaded, sign * abs(load_A), 0.0)


def run_case(index: int, seed: int, brake: bool, folder: Path) -> dict[str, Any]:
    """Simulate one reversing efficiency run and score η and its interval."""
    rng = np.random.default_rng([seed, index])
    stand = load_stand(STAND)
    motor_in, motor_out = load_motor(stand.motor_in), load_motor(stand.motor_out)
    reducer = stand.reducer_params()
    eta = float(rng.uniform(0.6, 0.95))
    reducer = ReducerParams(**{**reducer.__dict__, "efficiency": eta})
    dt = stand.sample_period_s
    samples = int(round(RUN_DURATION_S / dt))
    load_A = float(rng.uniform(0.3, 0.6)) * motor_out.limits.current_A
    speed = float(rng.uniform(0.2, 0.5)) * motor_in.limits.speed_rad_s
    kt_in, kt_out = motor_in.motor_params().Kt, motor_out.motor_params().Kt
    load_nm = kt_out * load_A
    friction_in = float(rng.uniform(0.02, 0.2)) * load_nm / (reducer.ratio * eta)
    friction_out = float(rng.uniform(0.02, 0.2)) * load_nm
    plant = ReducerPlant(
        motor_in.motor_params(), motor_out.motor_params(), reducer,
        motor_in.drive_params("speed"), motor_out.drive_params("current"),
        motor_in.sensor_params(),
        Effects.from_mapping({"coulomb_friction": {"Tc": friction_in}}),
        Effects.from_mapping({"coulomb_friction": {"Tc": friction_out}}),
        seed=seed * 100_003 + index)
    speed_cmd, load_cmd = reversing_commands(samples, speed, load_A, brake)
    run = simulate_reducer(plant, [("speed", speed_cmd), ("current", load_cmd)], dt)
    path = write_run(folder / f"reducer{index}.csv", {c: run[c] for c in run.columns})
    row: dict[str, Any] = {"index": index, "truth": eta, "friction_in_Nm": friction_in,
                           "friction_out_Nm": friction_out}
    try:
        r = efficiency(read_run(path, "reducer"), reducer.ratio, kt_in, kt_out)
    except StandError as exc:
        return {**row, "error": str(exc)}
    low, high = r.efficiency_ci95
    return {**row, "efficiency": r.efficiency, "error_abs": r.efficiency - eta,
            "covered": bool(low <= eta <= high), "half_width": (high - low) / 2,
            "steps": r.steps, "warnings": r.warnings}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=20)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--load", choices=("brake", "one-sign"), default="brake",
                        help="the load opposes the motion in both directions, or keeps a sign")
    parser.add_argument("--rows", type=Path, help="write every case as JSON lines here")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="efficiency-bench-") as tmp:
        rows = [run_case(k, args.seed, args.load == "brake", Path(tmp))
                for k in range(args.cases)]
    ok = [r for r in rows if "error_abs" in r]
    err = np.array([abs(r["error_abs"]) for r in ok])
    summary = {
        "cases": len(rows), "refused": len(rows) - len(ok),
        "within_0.01": float(np.mean(err <= 0.01)) if ok else None,
        "coverage": float(np.mean([r["covered"] for r in ok])) if ok else None,
        "median_abs_error": float(np.median(err)) if ok else None,
        "max_abs_error": float(np.max(err)) if ok else None,
        "median_half_width": float(np.median([r["half_width"] for r in ok])) if ok else None,
        "steps_kept": sorted({r["steps"] for r in ok}),
    }
    if args.rows:
        args.rows.write_text("".join(json.dumps(r, default=str) + "\n" for r in rows))
    json.dump(summary, sys.stdout, indent=1)
    print()
    return 0 if not math.isnan(summary["median_abs_error"] or 0.0) else 1


if __name__ == "__main__":
    raise SystemExit(main())
