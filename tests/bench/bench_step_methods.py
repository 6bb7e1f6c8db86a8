"""Seed 001's comparison rerun on simulated data: LM, trust region, gradient descent, pattern search.

Run: ``python tests/bench/bench_step_methods.py [--seed N] [--coverage RUNS]``

Data: the seed's motor (profile ms150_dcm150f), one 8.5 V step, 5 s at 1 kHz, tacho noise
0.05 rad/s, current noise 5 mA. Prints, per method, the transfer function, fit %, its error
against the one the seed's parameters give, the time, and (with the current measured)
the largest error of the five physical parameters; then the seed's published transfer
functions scored on the same data. ``--coverage`` also checks on many noise seeds that
the reported 95 % intervals cover the truth about 95 % of the time.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from stand.runfile import Run, check_columns
from stand.stepid import METHODS, PARAM_NAMES, coefficients, identify_steps
from stand.stepid.model import respond, step_data
from stand.stepid.simulated import simulate_step_run
from stand.stepid.stats import fit_percent

#: Seed 001 §3 parameters: R Ω, L H, K N·m/A, J kg·m², Kf N·m·s/rad.
SEED_PARAMS = np.array([2.937, 0.040437, 0.6571, 0.064744, 0.04867])
#: The seed's published transfer functions (b0, a1, a0).
SEED_TFS = {
    "NLS trust region (seed)": (251.2, 73.43, 219.7),
    "gradient descent (seed)": (251.0, 73.38, 219.5),
    "NLS Levenberg (seed)": (252.2, 73.37, 221.0),
    "pattern search (seed)": (247.7, 73.57, 214.8),
    "System Identification Toolbox (seed)": (233.4, 68.26, 204.1),
}
NAMES = {"trf": "NLS trust region", "lm": "NLS Levenberg", "gd": "gradient descent",
         "pattern": "pattern search"}


def speed_only(run: Run) -> Run:
    return check_columns({k: run[k] for k in ("time_s", "voltage_V", "velocity_rad_s")},
                         "step", run.source)


def tf_text(b0: float, a1: float, a0: float) -> str:
    return f"{b0:.1f}/(s²+{a1:.2f}s+{a0:.1f})"


def comparison(seed: int) -> None:
    run = simulate_step_run("ms150_dcm150f", [8.5], 5.0, seed=seed)
    truth = coefficients(SEED_PARAMS, False)
    print(f"# one 8.5 V step, 5 s at 1 kHz, noise seed {seed}; true TF {tf_text(*truth)}")
    print("| method | transfer function (speed only) | fit % | max TF error % | time s "
          "| evaluations | converged | max parameter error % (with current) | time s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for method in METHODS:
        started = time.perf_counter()
        result = identify_steps([speed_only(run)], method=method)
        elapsed = time.perf_counter() - started
        tf = np.array(result.transfer_function["num"] + result.transfer_function["den"][1:])
        started = time.perf_counter()
        full = identify_steps([run], method=method)
        elapsed_full = time.perf_counter() - started
        params = np.array([full.params[name] for name in PARAM_NAMES], dtype=float)
        print(f"| {NAMES[method]} ({method}) | {tf_text(*tf)} | {result.fit_percent:.3f} "
              f"| {100 * np.max(np.abs(tf / truth - 1)):.2f} | {elapsed:.2f} | {result.nfev} "
              f"| {'yes' if result.converged else 'no'} "
              f"| {100 * np.max(np.abs(params / SEED_PARAMS - 1)):.2f} | {elapsed_full:.2f} |")
    data = step_data([speed_only(run)])[0]
    for name, tf in SEED_TFS.items():
        model = respond(np.array(tf), data)[0]
        error = 100 * np.max(np.abs(np.array(tf) / truth - 1))
        print(f"| {name} | {tf_text(*tf)} | {fit_percent(data.velocity_rad_s, model):.3f} "
              f"| {error:.2f} | | | | | |")


def coverage(runs: int) -> None:
    hits = {"speed only, TF": 0, "with current, parameters": 0}
    z_speed, z_full = [], []
    truth_tf = coefficients(SEED_PARAMS, False)
    for k in range(runs):
        run = simulate_step_run("ms150_dcm150f", [8.5], 5.0, seed=1000 + k)
        speed = identify_steps([speed_only(run)])
        tf = np.array(speed.transfer_function["num"] + speed.transfer_function["den"][1:])
        sd = np.array(speed.transfer_function_std["num"] + speed.transfer_function_std["den"][1:])
        z_speed.append((tf - truth_tf) / sd)
        full = identify_steps([run])
        est = np.array([full.params[n] for n in PARAM_NAMES], dtype=float)
        sd_full = np.array([full.std[n] for n in PARAM_NAMES], dtype=float)
        z_full.append((est - SEED_PARAMS) / sd_full)
    zs, zf = np.abs(np.array(z_speed)), np.abs(np.array(z_full))
    hits["speed only, TF"] = int(np.sum(zs < 1.96))
    hits["with current, parameters"] = int(np.sum(zf < 1.96))
    print(f"# coverage of the 95 % intervals over {runs} noise seeds")
    print(f"speed only: {100 * hits['speed only, TF'] / zs.size:.1f} % of {zs.size} TF "
          f"coefficients inside; RMS z {np.sqrt(np.mean(zs ** 2)):.2f}")
    print(f"with current: {100 * hits['with current, parameters'] / zf.size:.1f} % of "
          f"{zf.size} parameters inside; RMS z per parameter "
          + ", ".join(f"{n} {v:.2f}" for n, v in zip(PARAM_NAMES, np.sqrt(np.mean(zf ** 2, axis=0)),
                                                      strict=True)))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1, help="noise seed of the comparison")
    parser.add_argument("--coverage", type=int, default=0, metavar="RUNS",
                        help="also check interval coverage over RUNS noise seeds")
    args = parser.parse_args(argv)
    comparison(args.seed)
    if args.coverage:
        coverage(args.coverage)
    return 0


if __name__ == "__main__":
    sys.exit(main())
