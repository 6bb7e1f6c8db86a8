"""Convergence and cost of the simulated plant's integration (stand/physics/plant.py).

A few representative stands (current and speed mode, with and without friction, cogging
and ripple, backlash, 1–5 ms sampling) are simulated without noise and with an ideal
encoder at several longest sub-steps (``MAX_SUBSTEP_S``). Each run is compared with the
same run at the finest sub-step: the largest deviation of the sampled angle (as a share of
the angle's range) and of the sampled current (as a share of the drive level). A plant
that integrates the continuous system faithfully shows deviations that shrink fast with
the sub-step and are already small at the default one.

The cost is the wall time of one :meth:`MotorPlant.advance` of a 2 ms sample period at
the default sub-step (the work of a simulated drive on the bus per SYNC), median of
several repeats.

    python tests/bench/bench_plant.py
    python tests/bench/bench_plant.py --substeps 1e-4 3e-5 1e-5 3e-6 --reference 1e-6
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import Any

import numpy as np

import stand.physics.plant as plant_module
from stand.excitation import excitation
from stand.physics.effects import Effects
from stand.physics.parts import DriveParams, MotorParams, SensorParams
from stand.physics.plant import MotorPlant
from stand.physics.simulate import simulate_motor

RUN_DURATION_S = 2.0


def stands() -> list[dict[str, Any]]:
    """The representative stands: name, motor, drive, effects, period, excitation."""
    motor = MotorParams(R=1.2, L=8e-4, Kt=0.06, J=5e-5, D=5e-5)
    level_i = 1.0  # A
    level_w = 60.0  # rad/s
    torque = motor.Kt * level_i
    current = DriveParams(mode="current", supply_V=48.0, current_limit_A=20.0,
                          current_tau_s=2e-4)
    kp = 2 * math.pi * 20.0 * motor.J / motor.Kt
    speed = DriveParams(mode="speed", supply_V=48.0, current_limit_A=20.0,
                        current_tau_s=2e-4, speed_kp=kp, speed_ki=kp * 2 * math.pi * 20.0 / 5)
    coulomb = {"coulomb_friction": {"Tc": 0.1 * torque}}
    stribeck = {"stribeck_friction": {"Tc": 0.05 * torque, "Ts": 0.15 * torque, "ws": 3.0}}
    cogging = {"cogging": {"Tcog": 0.1 * torque, "N": 12, "phi": 0.3},
               "torque_ripple": {"eps": 0.1, "N": 6, "phi": 1.0}}
    backlash = {"backlash": {"gap": 0.01, "J_load": 5e-5}}
    rows = [
        ("current, none, 1 ms", current, {}, 1e-3),
        ("current, none, 5 ms", current, {}, 5e-3),
        ("current, coulomb, 2 ms", current, coulomb, 2e-3),
        ("current, stribeck, 3 ms", current, stribeck, 3e-3),
        ("current, cogging+ripple, 2 ms", current, cogging, 2e-3),
        ("current, backlash, 2 ms", current, backlash, 2e-3),
        ("speed, none, 2 ms", speed, {}, 2e-3),
        ("speed, coulomb, 4 ms", speed, coulomb, 4e-3),
        ("speed, stribeck, 1 ms", speed, stribeck, 1e-3),
    ]
    return [{"name": name, "motor": motor, "drive": drive, "effects": effects, "dt": dt,
             "level": level_i if drive.mode == "current" else level_w}
            for name, drive, effects, dt in rows]


def run(stand: dict[str, Any], substep_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Sampled angle and current of ``stand`` integrated with sub-steps <= ``substep_s``."""
    saved = plant_module.MAX_SUBSTEP_S
    plant_module.MAX_SUBSTEP_S = substep_s
    try:
        plant = MotorPlant(stand["motor"], stand["drive"], SensorParams(encoder_lines=0),
                           Effects.from_mapping(stand["effects"]), seed=0)
        samples = int(round(RUN_DURATION_S / stand["dt"]))
        hold = max(1, int(round(0.05 / stand["dt"])))
        command = excitation("prbs", samples, stand["dt"], 0.0, stand["level"], hold, seed=7)
        result = simulate_motor(plant, stand["drive"].mode, command, stand["dt"])
    finally:
        plant_module.MAX_SUBSTEP_S = saved
    return result["position_rad"], result["current_A"]


def convergence(substeps: list[float], reference: float) -> list[dict[str, Any]]:
    """Per stand and sub-step: largest angle and current deviation from the reference."""
    rows = []
    for stand in stands():
        theta_ref, i_ref = run(stand, reference)
        span = float(np.ptp(theta_ref)) or 1.0
        level = float(np.max(np.abs(i_ref))) or 1.0
        row: dict[str, Any] = {"stand": stand["name"]}
        for h in substeps:
            theta, i = run(stand, h)
            row[f"{h:g}"] = {"angle": float(np.max(np.abs(theta - theta_ref)) / span),
                             "current": float(np.max(np.abs(i - i_ref)) / level)}
        rows.append(row)
    return rows


def cost(repeats: int = 2000) -> dict[str, float]:
    """Wall time of one 2 ms ``advance`` at the default sub-step, µs (median of 7)."""
    figures = {}
    for stand in stands():
        if stand["name"] not in ("current, none, 1 ms", "current, coulomb, 2 ms",
                                 "speed, coulomb, 4 ms", "current, backlash, 2 ms"):
            continue
        plant = MotorPlant(stand["motor"], stand["drive"], SensorParams(),
                           Effects.from_mapping(stand["effects"]), seed=0)
        plant.command(stand["drive"].mode, stand["level"])
        times = []
        for _ in range(7):
            start = time.perf_counter()
            for k in range(repeats):
                if k % 25 == 0:
                    plant.command(stand["drive"].mode, -plant.armature.target or stand["level"])
                plant.advance(2e-3)
            times.append((time.perf_counter() - start) / repeats * 1e6)
        figures[stand["name"]] = float(np.median(times))
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--substeps", type=float, nargs="+", default=[1e-4, 3e-5, 1e-5, 3e-6])
    parser.add_argument("--reference", type=float, default=1e-6)
    parser.add_argument("--no-cost", action="store_true")
    args = parser.parse_args(argv)
    out: dict[str, Any] = {"default_substep_s": plant_module.MAX_SUBSTEP_S,
                           "convergence": convergence(args.substeps, args.reference)}
    if not args.no_cost:
        out["advance_2ms_us"] = cost()
    json.dump(out, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
