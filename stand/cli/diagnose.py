"""``stand diagnose TRAIN.csv --holdout HOLDOUT.csv``: the sim-to-real gap (CONTRACT §3)."""

from __future__ import annotations

import argparse
from dataclasses import replace
from typing import Any

from stand import Diagnosis, InputError, diagnose, read_run
from stand.cli import options
from stand.diagnosis.engine import ANCHOR_HORIZON_S, MAX_EFFECTS, diagnose_with_traces
from stand.ident.supply import motor_supply


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("train", type=options.input_file,
                        help="run file the models are identified on (CSV, single motor)")
    parser.add_argument("--holdout", required=True, type=options.input_file,
                        help="run file the models are scored on (CSV, single motor)")
    parser.add_argument("--kt", type=options.positive, default=None,
                        help="torque constant, N·m/A: also report torques in N·m")
    parser.add_argument("--horizon", type=options.positive, default=ANCHOR_HORIZON_S,
                        help="free-run time between re-anchorings of the simulation, s")
    parser.add_argument("--max-effects", type=options.whole(1, 8), default=MAX_EFFECTS,
                        help="most effects combined in the verdict")
    parser.add_argument("--spring", action="store_true",
                        help="keep seed 000's spring term C·θ in the nominal model")
    parser.add_argument("--plot", metavar="DIR", type=options.output_dir,
                        help="write PNG figures to this folder")
    parser.add_argument("--motor", default=None, metavar="PROFILE",
                        help="motor profile (name or YAML path) whose drive's current limit "
                             "clips a speed loop's kicks between samples")


def run(args: argparse.Namespace) -> Diagnosis:
    train = read_run(args.train, "single")
    holdout = read_run(args.holdout, "single")
    if args.kt is not None and not args.kt > 0:
        raise InputError(f"--kt must be > 0 N·m/A, got {args.kt}")
    options = dict(kt=args.kt, horizon_s=args.horizon, max_effects=args.max_effects,
                   spring=args.spring, supply=motor_supply(args.motor))
    if not args.plot:
        return diagnose(train, holdout, **options)
    from stand.diagnosis.plots import write_plots

    result, traces = diagnose_with_traces(train, holdout, **options)
    return replace(result, plots=[str(p) for p in write_plots(args.plot, result, traces)])


def _place(where: dict[str, Any]) -> str:
    place = str(where["regime"])
    for key, unit in (("cycles_per_rev", " cycles/rev"), ("band_hz", " Hz"), ("lag_s", " s")):
        if where.get(key) is not None:
            place += f", {key} {where[key]}{unit}"
    for key in ("velocity_sign_energy", "current_level_energy"):
        if where.get(key):
            place += f", {key.split('_energy')[0]} " + " ".join(
                f"{k} {v:.2f}" for k, v in where[key].items())
    return place


def summarize(result: dict[str, Any]) -> str:
    noise = result.get("noise_gap_percent")
    replayed = result.get("replayed_noise_gap_percent")
    lines = [
        f"gap {result['gap_percent']:.2f} % of the holdout speed "
        f"(quantization floor {result['noise_floor_percent']:.2f} %"
        + (f", noise explains {noise:.2f} %" if noise is not None else "")
        + (f", {replayed:.2f} % on replays of the run" if replayed is not None else "")
        + f"), where: {_place(result['where'])}",
        f"verdict: {result['verdict']} (gap with it {result['verdict_gap_percent']:.2f} %)",
        "effect               gap %   shrink  significant  params",
    ]
    for e in result["effects"]:
        params = ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                           for k, v in e["params"].items())
        lines.append(f"{e['effect']:<20} {e['gap_percent']:6.2f}  {e['shrink']:7.2f}  "
                     f"{'yes' if e['significant'] else 'no':<11}  {params}")
    lines += [f"in the verdict after {'+'.join(s['after'])}: {s['effect']} "
              f"(gap {s['gap_before_percent']:.2f} -> {s['gap_percent']:.2f} %, shrink "
              f"{s['shrink']:.2f}, p {s['p_value']:.2g})"
              for s in result.get("steps", []) if s["after"]]
    if result.get("residual_where") and result["verdict"] != "none":
        lines.append(f"what remains lies: {_place(result['residual_where'])}")
    if result.get("model"):
        lines.append("model with the verdict's effects: " + ", ".join(
            f"{k}={v:.4g}" for k, v in result["model"].items() if isinstance(v, float)))
    lines += [f"note: {note}" for note in result.get("notes", [])]
    if result.get("plots"):
        lines.append("plots: " + ", ".join(result["plots"]))
    return "\n".join(lines)
