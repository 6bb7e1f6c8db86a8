"""Bias and interval coverage of ``stand identify`` on random simulated stands.

Each case draws a motor (J 5e-6…5e-4 kg·m², Kt 0.02…0.2 N·m/A, J/D 0.05…2 s), a sample
period of 1–5 ms, a drive mode with reversing excitation (current mode: PRBS currents
of ± the drive level; speed mode: reversing PRBS speed steps under a PI loop of 2–40 Hz),
an encoder, current noise of 0.5–5 % of the drive level, and one effect set: none,
each identifiable effect of the vocabulary alone, and every pair (cycled by case
index). The run is written to CSV and read back; ``identify_run`` sees only that.

Figures: share of cases with Kt/J within 2 % of the truth, share whose 95 % interval
holds the truth (overall, per effect, per mode), the estimators picked, and, for speed
mode, the error against ``π·f_loop·Δt`` (the inertial current a loop faster than the
sampling hides between samples, :mod:`docs/results/ident.md`).

    python tests/bench/bench_ident_coverage.py --cases 110 --seed 1 --workers 2
    python tests/bench/bench_ident_coverage.py --kt --stands 20 --seed 1   # 5 + 5 repeats
    python tests/bench/bench_ident_coverage.py --timing   # the current between samples
    python tests/bench/bench_ident_coverage.py --mode speed --no-target   # one mode, no target
    python tests/bench/bench_ident_coverage.py --mode speed --no-supply   # supply not told
    python tests/bench/bench_ident_coverage.py --supply-cost   # CPU s of one 20 s, 1 kHz run
    python tests/bench/bench_ident_coverage.py --replicates 6 --cases 40 --seed 14 --mode current

``--replicates R`` runs each stand R times (fresh excitation and noise, the same motor,
drive and effects) and compares the spread of Kt/J over the runs with the standard error
each run reports (a ratio below 1: the errors are wider than the noise needs) and the mean
error with it (a bias every run of the stand shares, which no interval from one run sees).

``identify`` is told the drive's supply (48 V) and current limit, and the motor's R, L and
Kt each off by a factor of up to 1.25 either way (a profile's values, which the
speed-loop refinement refits); ``--no-supply`` tells it nothing.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from stand.errors import StandError
from stand.excitation import excitation
from stand.ident.identify import identify_run
from stand.ident.select import IDENT_EFFECTS
from stand.ident.supply import DriveSupply
from stand.ident.torque_constant import torque_constant
from stand.physics.effects import Effects
from stand.physics.parts import DriveParams, MotorParams, SensorParams
from stand.physics.plant import MotorPlant
from stand.physics.simulate import simulate_motor
from stand.runfile import CURRENT_MEAN_COLUMN, read_run, write_run

#: Effect sets cycled over the cases: none, each alone, each pair.
EFFECT_SETS: list[tuple[str, ...]] = [(), *((e,) for e in IDENT_EFFECTS),
                                      *itertools.combinations(IDENT_EFFECTS, 2)]
RUN_DURATION_S = 6.0
ENCODER_LINES = (500, 1000, 2000, 2500, 4096, 5000)


def _log_uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(math.exp(rng.uniform(math.log(low), math.log(high))))


def draw_stand(rng: np.random.Generator, mode: str | None = None) -> dict[str, Any]:
    """A motor, drive, sensors and reversing excitation (no effects)."""
    J = _log_uniform(rng, 5e-6, 5e-4)
    Kt = _log_uniform(rng, 0.02, 0.2)
    motor = MotorParams(R=_log_uniform(rng, 0.5, 5.0), L=_log_uniform(rng, 2e-4, 3e-3), Kt=Kt,
                        J=J, D=J / _log_uniform(rng, 0.05, 2.0))
    dt = float(rng.uniform(1e-3, 5e-3))
    mode = mode or ("current" if rng.random() < 0.6 else "speed")
    omega_ref = min(_log_uniform(rng, 20.0, 200.0), 0.4 * 48.0 / Kt)
    hold_s = _log_uniform(rng, 0.02, 0.3) if mode == "current" else _log_uniform(rng, 0.1, 0.5)
    current_ref = J * omega_ref / (Kt * hold_s) + motor.D * omega_ref / Kt
    loop_hz = _log_uniform(rng, 2.0, 40.0)
    kp = 2 * math.pi * loop_hz * J / Kt
    drive = DriveParams(mode=mode, supply_V=48.0, current_limit_A=20.0 * current_ref,  # type: ignore[arg-type]
                        current_tau_s=2e-4, speed_kp=kp, speed_ki=kp * 2 * math.pi * loop_hz / 5)
    sensors = SensorParams(encoder_lines=int(rng.choice(ENCODER_LINES)),
                           current_noise_A=_log_uniform(rng, 0.005, 0.05) * current_ref)
    return {"motor": motor, "drive": drive, "sensors": sensors, "mode": mode, "dt": dt,
            "hold": max(1, int(round(hold_s / dt))), "loop_hz": loop_hz,
            "level": current_ref if mode == "current" else omega_ref, "current_ref": current_ref,
            "omega_ref": omega_ref}


def draw_effect(name: str, rng: np.random.Generator, stand: dict[str, Any]) -> dict[str, float]:
    """Parameters of effect ``name`` at 3–30 % of the drive torque."""
    torque = stand["motor"].Kt * stand["current_ref"]
    strength = _log_uniform(rng, 0.03, 0.3)
    order_max = 24
    if name == "coulomb_friction":
        return {"Tc": strength * torque}
    if name == "stribeck_friction":
        Ts = strength * torque
        return {"Tc": Ts * rng.uniform(0.2, 0.6), "Ts": Ts,
                "ws": stand["omega_ref"] * _log_uniform(rng, 0.03, 0.3)}
    if name == "cogging":
        return {"Tcog": strength * torque, "N": int(rng.integers(2, order_max + 1)),
                "phi": rng.uniform(0, 2 * math.pi)}
    if name == "current_offset":
        return {"i0": strength * stand["current_ref"] * float(rng.choice([-1.0, 1.0]))}
    if name == "delay":
        return {"k": int(rng.integers(1, 5))}
    return {"eps": _log_uniform(rng, 0.03, 0.3), "N": int(rng.integers(2, order_max + 1)),
            "phi": rng.uniform(0, 2 * math.pi)}


#: Columns written to each run file; ``--no-target`` leaves out the speed target (a
#: stand that does not record what it commanded).
RUN_COLUMNS = ["time_s", "current_A", "position_rad", "speed_target_rad_s"]


def simulate(stand: dict[str, Any], effects: dict[str, dict[str, float]], seed: int,
             added_inertia: float = 0.0, folder: Path | None = None,
             target: bool = True, current_mean: bool = False) -> Any:
    """One run of ``stand``, written as CSV (:data:`RUN_COLUMNS`, and with
    ``current_mean`` the drive's current averaged over each period,
    :data:`~stand.runfile.CURRENT_MEAN_COLUMN`) and read back."""
    motor = stand["motor"]
    if added_inertia:
        motor = MotorParams(R=motor.R, L=motor.L, Kt=motor.Kt, J=motor.J + added_inertia,
                            D=motor.D)
    plant = MotorPlant(motor, stand["drive"], stand["sensors"], Effects.from_mapping(effects),
                       seed=seed)
    samples = int(round(RUN_DURATION_S / stand["dt"]))
    command = excitation("prbs", samples, stand["dt"], 0.0, stand["level"], stand["hold"],
                         seed=seed)
    run = simulate_motor(plant, stand["mode"], command, stand["dt"], current_mean=current_mean)
    with tempfile.TemporaryDirectory(prefix="ident-bench-") as tmp:
        path = write_run(Path(folder or tmp) / f"run{seed}.csv",
                         {c: run[c] for c in [*RUN_COLUMNS, CURRENT_MEAN_COLUMN]
                          if c in run and (target or c != "speed_target_rad_s")})
        return read_run(path, "single")


#: Largest factor by which the R, L and Kt told to ``identify`` are off the truth.
PROFILE_ERROR = 1.25


def told_supply(stand: dict[str, Any], rng: np.random.Generator) -> DriveSupply:
    """What a user knows of ``stand``'s drive: its supply, current limit and speed-loop
    gains exactly (settings), and R, L, Kt off by up to :data:`PROFILE_ERROR` either way
    (log-uniform)."""
    motor, drive = stand["motor"], stand["drive"]
    off = [_log_uniform(rng, 1 / PROFILE_ERROR, PROFILE_ERROR) for _ in range(3)]
    return DriveSupply(drive.supply_V, motor.R * off[0], motor.L * off[1], motor.Kt * off[2],
                       drive.current_limit_A, drive.speed_kp, drive.speed_ki)


def case_mode(index: int, seed: int) -> str:
    """Drive mode of case ``index`` (the same draw as :func:`run_case`)."""
    return str(draw_stand(np.random.default_rng([seed, index]))["mode"])


def kt_mode(index: int, seed: int) -> str:
    """Drive mode of stand ``index`` of the ``--kt`` part."""
    return str(draw_stand(np.random.default_rng([seed, index, 1]))["mode"])


#: Start of the warning of a speed loop whose current is not reconstructed.
NOT_RECONSTRUCTED = "the PI speed law explains"


def draw_case(index: int, seed: int, supply: bool = True
              ) -> tuple[dict[str, Any], tuple[str, ...], dict[str, dict[str, float]],
                         DriveSupply | None]:
    """Stand, effect set, effects and the supply told to ``identify`` of case ``index``."""
    rng = np.random.default_rng([seed, index])
    stand = draw_stand(rng)
    names = EFFECT_SETS[index % len(EFFECT_SETS)]
    effects = {name: draw_effect(name, rng, stand) for name in names}
    told = told_supply(stand, np.random.default_rng([seed, index, 2])) if supply else None
    return stand, names, effects, told


def run_case(index: int, seed: int, target: bool = True, supply: bool = True,
             current_mean: bool = False) -> dict[str, Any]:
    """Draw, simulate and identify case ``index``; score Kt/J and its interval
    (``current_mean``: the run also holds the drive's period-mean current)."""
    stand, names, effects, told = draw_case(index, seed, supply)
    run = simulate(stand, effects, seed * 100_003 + index, target=target,
                   current_mean=current_mean)
    truth = stand["motor"].Kt / stand["motor"].J
    row: dict[str, Any] = {"index": index, "truth_effects": list(names), "mode": stand["mode"],
                           "dt_s": stand["dt"], "loop_hz": stand["loop_hz"]}
    start = time.perf_counter()
    try:
        r = identify_run(run, supply=told)
    except StandError as exc:
        return {**row, "error": str(exc), "seconds": time.perf_counter() - start}
    low, high = r.Kt_over_J_ci95
    return {**row, "seconds": time.perf_counter() - start,
            "error_rel": r.Kt_over_J / truth - 1.0, "covered": bool(low <= truth <= high),
            "half_width_rel": (high - low) / 2 / truth, "found": r.effects,
            "estimator": r.estimator, "warnings": r.warnings, "current_input": r.current_input}


#: Seed step between the runs of one stand in ``--replicates``.
REPLICATE_STRIDE = 7919


def run_replicates(index: int, seed: int, target: bool = True, supply: bool = True,
                   replicates: int = 6) -> dict[str, Any]:
    """Stand ``index`` run ``replicates`` times (the first is :func:`run_case`'s run): the
    spread of Kt/J over the runs and its mean error, in the runs' mean standard error."""
    stand, names, effects, told = draw_case(index, seed, supply)
    truth = stand["motor"].Kt / stand["motor"].J
    errors, ses, covered = [], [], []
    for k in range(replicates):
        run = simulate(stand, effects, seed * 100_003 + index + REPLICATE_STRIDE * k,
                       target=target)
        try:
            r = identify_run(run, supply=told)
        except StandError:
            continue
        errors.append(r.Kt_over_J / truth - 1.0)
        ses.append(r.Kt_over_J_se / truth)
        covered.append(r.Kt_over_J_ci95[0] <= truth <= r.Kt_over_J_ci95[1])
    row: dict[str, Any] = {"index": index, "truth_effects": list(names),
                           "mode": stand["mode"], "runs": len(errors)}
    if len(errors) < 2:
        return row
    se = float(np.mean(ses))
    return {**row, "mean_error_rel": float(np.mean(errors)), "mean_se_rel": se,
            "spread_over_se": float(np.std(errors, ddof=1)) / se,
            "bias_over_se": float(np.mean(errors)) / se,
            "covered": float(np.mean(covered))}


def summarize_replicates(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Median spread and |bias| over the reported standard error, and the coverage."""
    ok = [r for r in rows if "spread_over_se" in r]
    if not ok:
        return {"stands": len(rows), "answered": 0}
    spread = np.array([r["spread_over_se"] for r in ok])
    bias = np.array([abs(r["bias_over_se"]) for r in ok])
    return {"stands": len(rows), "answered": len(ok), "runs": sum(r["runs"] for r in ok),
            "spread_over_se_quartiles": np.percentile(spread, [25, 50, 75]).tolist(),
            "abs_bias_over_se_quartiles": np.percentile(bias, [25, 50, 75]).tolist(),
            "stands_biased_beyond_2_se": int(np.sum(bias > 2.0)),
            "coverage": float(np.mean([r["covered"] for r in ok]))}


def summarize(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Within-2 % share and coverage, overall, per effect and per mode."""
    ok = [r for r in rows if "error_rel" in r]

    def figures(part: list[dict[str, Any]]) -> dict[str, Any]:
        if not part:
            return {"cases": 0}
        err = np.array([abs(r["error_rel"]) for r in part])
        return {"cases": len(part), "within_2pct": float(np.mean(err <= 0.02)),
                "coverage": float(np.mean([r["covered"] for r in part])),
                "median_abs_error": float(np.median(err)),
                "median_half_width": float(np.median([r["half_width_rel"] for r in part]))}

    per_effect: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for r in ok:
        for name in r["truth_effects"] or ["none"]:
            per_effect[name].append(r)
    speed = [r for r in ok if r["mode"] == "speed"]
    plain = [r for r in speed if any(w.startswith(NOT_RECONSTRUCTED) for w in r["warnings"])]
    hidden = [r["error_rel"] - math.pi * r["loop_hz"] * r["dt_s"] for r in speed]
    return {
        "cases": len(rows), "refused": len(rows) - len(ok), "all": figures(ok),
        "per_mode": {m: figures([r for r in ok if r["mode"] == m]) for m in ("current", "speed")},
        "speed_reconstructed": figures([r for r in speed if r not in plain]),
        "speed_not_reconstructed": figures(plain),
        "per_effect": {k: figures(v) for k, v in sorted(per_effect.items())},
        "estimators": {e: sum(r["estimator"] == e for r in ok) for e in ("bc", "iv", "ls")},
        "speed_error_less_pi_f_dt_median": float(np.median(hidden)) if hidden else None,
        "median_seconds": float(np.median([r["seconds"] for r in rows])),
    }


def run_kt_case(index: int, seed: int, target: bool = True,
                supply: bool = True, current_mean: bool = False) -> dict[str, Any]:
    """Torque constant from 5 + 5 repeats on one random stand with one random effect."""
    rng = np.random.default_rng([seed, index, 1])
    stand = draw_stand(rng)
    names = EFFECT_SETS[index % (1 + len(IDENT_EFFECTS))]
    effects = {name: draw_effect(name, rng, stand) for name in names}
    added = stand["motor"].J * _log_uniform(rng, 0.5, 2.0)
    base = seed * 100_003 + 1000 * index
    free = [simulate(stand, effects, base + k, target=target, current_mean=current_mean)
            for k in range(5)]
    loaded = [simulate(stand, effects, base + 10 + k, added, target=target,
                       current_mean=current_mean) for k in range(5)]
    row: dict[str, Any] = {"index": index, "truth_effects": list(names), "mode": stand["mode"],
                           "dt_s": stand["dt"]}
    told = told_supply(stand, np.random.default_rng([seed, index, 3])) if supply else None
    try:
        r = torque_constant(free, loaded, added, supply=told)
    except StandError as exc:
        return {**row, "error": str(exc)}
    low, high = r.Kt_ci95
    truth = stand["motor"].Kt
    return {**row, "error_rel": r.Kt / truth - 1.0, "covered": bool(low <= truth <= high),
            "half_width_rel": (high - low) / 2 / truth, "warnings": r.warnings}


def timing_figures() -> dict[str, Any]:
    """Kt/J error on noise-free, unquantized current-mode PRBS runs at 3 ms (4 seeds):
    the samples taken as point values (seed 000's model, ``--effects none``) against the
    current held over each period (the extended model, ``--effects auto``)."""
    motor = MotorParams(R=2.0, L=1e-3, Kt=0.05, J=2e-5, D=4e-5)
    out: dict[str, list[float]] = {"point_samples": [], "held_current": []}
    for seed in range(4):
        plant = MotorPlant(motor, DriveParams(mode="current", supply_V=48.0,
                                              current_limit_A=10.0),
                           SensorParams(encoder_lines=0, current_noise_A=0.0), Effects(),
                           seed=seed)
        command = excitation("prbs", 2000, 3e-3, 0.0, 0.3, 17, seed=seed)
        run = simulate_motor(plant, "current", command, 3e-3)
        truth = motor.Kt / motor.J
        out["point_samples"].append(identify_run(run, effects="none").Kt_over_J / truth - 1)
        out["held_current"].append(identify_run(run).Kt_over_J / truth - 1)
    return out


def supply_cost(duration_s: float = 20.0, dt: float = 1e-3) -> dict[str, Any]:
    """CPU seconds of one identification of a 20 Hz speed loop on a 6 V drive (its kicks
    saturate the supply; PRBS speed steps of ±60 rad/s held 0.2 s, ``duration_s`` at
    ``dt``), without and with the supply told (R, L, Kt 10-20 % off), and Kt/J's error."""
    motor = MotorParams(R=2.0, L=1e-3, Kt=0.05, J=2e-5, D=4e-5)
    kp = 2 * math.pi * 20.0 * motor.J / motor.Kt
    drive = DriveParams(mode="speed", supply_V=6.0, current_limit_A=50.0, speed_kp=kp,
                        speed_ki=kp * 2 * math.pi * 20.0 / 5)
    plant = MotorPlant(motor, drive, SensorParams(encoder_lines=2000, current_noise_A=0.005),
                       Effects(), seed=3)
    samples = int(round(duration_s / dt))
    command = excitation("prbs", samples, dt, 0.0, 60.0, int(round(0.2 / dt)), seed=3)
    run = simulate_motor(plant, "speed", command, dt)
    told = DriveSupply(6.0, motor.R * 1.2, motor.L / 1.2, motor.Kt * 1.1)
    out: dict[str, Any] = {"samples": samples}
    for name, supply in (("no_supply", None), ("supply", told)):
        start = time.process_time()
        r = identify_run(run, supply=supply)
        out[name] = {"cpu_seconds": time.process_time() - start,
                     "error_rel": r.Kt_over_J / (motor.Kt / motor.J) - 1.0}
    return out


def _pool_map(function: Any, jobs: list[tuple[Any, ...]],
              workers: int) -> list[dict[str, Any]]:
    if workers <= 1:
        return [function(*job) for job in jobs]
    import multiprocessing

    with multiprocessing.get_context("spawn").Pool(workers) as pool:
        return list(pool.starmap(function, jobs, chunksize=1))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=110)
    parser.add_argument("--stands", type=int, default=20, help="stands of the --kt part")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--kt", action="store_true", help="torque constant, 5 + 5 repeats")
    parser.add_argument("--mode", choices=("current", "speed"),
                        help="only the cases (stands) of this drive mode")
    parser.add_argument("--no-target", action="store_true",
                        help="leave the speed target out of the run files")
    parser.add_argument("--no-supply", action="store_true",
                        help="tell identify nothing of the drive's supply and the motor")
    parser.add_argument("--current-mean", action="store_true",
                        help="the drives also report their current averaged over each "
                        "sample period (column current_mean_A)")
    parser.add_argument("--rows", type=Path, help="write every case as JSON lines here")
    parser.add_argument("--supply-cost", action="store_true",
                        help="CPU seconds of identify on a 20 s, 1 kHz run that saturates "
                             "a 6 V supply, without and with the supply told")
    parser.add_argument("--replicates", type=int, default=0,
                        help="run each stand this many times: spread and bias in its se")
    parser.add_argument("--timing", action="store_true",
                        help="noise-free Kt/J error: point samples against the held current")
    args = parser.parse_args(argv)
    if args.supply_cost:
        json.dump(supply_cost(), sys.stdout, indent=1)
        print()
        return 0
    if args.timing:
        json.dump(timing_figures(), sys.stdout, indent=1)
        print()
        return 0
    if args.kt:
        jobs: list[tuple[Any, ...]] = [
            (k, args.seed, not args.no_target, not args.no_supply, args.current_mean)
            for k in range(args.stands)
            if args.mode is None or kt_mode(k, args.seed) == args.mode]
        rows = _pool_map(run_kt_case, jobs, args.workers)
        ok = [r for r in rows if "error_rel" in r]
        err = np.array([abs(r["error_rel"]) for r in ok])
        summary: dict[str, Any] = {
            "stands": len(rows), "refused": len(rows) - len(ok),
            "within_1pct": float(np.mean(err <= 0.01)) if ok else None,
            "coverage": float(np.mean([r["covered"] for r in ok])) if ok else None,
            "median_abs_error": float(np.median(err)) if ok else None,
            "per_mode": {m: float(np.mean([abs(r["error_rel"]) <= 0.01 for r in ok
                                           if r["mode"] == m] or [np.nan]))
                         for m in ("current", "speed")}}
    elif args.replicates:
        jobs = [(k, args.seed, not args.no_target, not args.no_supply, args.replicates)
                for k in range(args.cases)
                if args.mode is None or case_mode(k, args.seed) == args.mode]
        rows = _pool_map(run_replicates, jobs, args.workers)
        summary = summarize_replicates(rows)
    else:
        jobs = [(k, args.seed, not args.no_target, not args.no_supply, args.current_mean)
                for k in range(args.cases)
                if args.mode is None or case_mode(k, args.seed) == args.mode]
        rows = _pool_map(run_case, jobs, args.workers)
        summary = summarize(rows)
    if args.rows:
        args.rows.write_text("".join(json.dumps(r, default=str) + "\n" for r in rows))
    json.dump(summary, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
