"""``stand demo``: the whole simulated stand on the embedded virtual bus, start to finish.

Starts simulated CiA 402 drives on python-can's ``virtual`` bus, runs the seed 000
procedure over CANopen through the stand controller — no-load and added-inertia
repeats, then the two-motor efficiency run — identifies the torque constant and the
reducer efficiency, diagnoses the sim-to-real gap of the nominal model on a holdout
run, and writes run files, CAN traces and plots. The results are stored in the
service's database too, so ``stand serve`` shows them.
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path
from typing import Any

from stand.cli import options
from stand.errors import InputError
from stand.jsonable import to_jsonable
from stand.runner import SIMULATED_MASTER_OPTIONS
from stand.settings import get_settings

log = logging.getLogger("stand")

#: Demo defaults: repeats of each seed 000 run and their length at 1 kHz, s.
DEMO_REPEATS = 3
DEMO_DURATION_S = 5.0
DEMO_CHANNEL = "motorstand-demo"
#: Diagnosis runs: length, s, and speed excursion around standstill as a fraction of the
#: limit. They reverse: the seed's forward-only runs cannot tell Coulomb friction
#: (sign ω constant) from a current offset, so they do not let the diagnosis separate them.
DIAGNOSIS_DURATION_S = 5.0
DIAGNOSIS_SPEED_FRACTION = 0.3
DIAGNOSIS_BAND_HZ = 10.0
DIAGNOSIS_SEED = 100


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-o", "--output", type=options.output_dir,
                        help="directory for run files, traces and plots "
                             "(default: STAND_DATA_DIR/demo)")
    parser.add_argument("--repeats", type=options.whole(1, 100), default=DEMO_REPEATS,
                        help="repeats of the no-load and added-inertia runs (the seed: 5)")
    parser.add_argument("--duration", type=options.duration, default=DEMO_DURATION_S,
                        help="length of each identification run, s of stand time")
    parser.add_argument("--no-plots", action="store_true", help="skip the plots")


def _experiment(name: str, **changes: Any) -> Any:
    from stand.controller import load_experiment

    experiment = load_experiment(name)
    return type(experiment)(**{**experiment.model_dump(), **changes})


def _run_experiment(experiment: Any, out: Path) -> Any:
    from bus.adapters import BusConfig
    from bus.stand_bus import StandBus
    from stand.controller import StandController

    started = time.monotonic()
    last = [-1]

    def progress(fraction: float) -> None:
        tenth = int(fraction * 10)
        if tenth != last[0]:
            last[0] = tenth
            log.info("  %s: %3d %%", experiment.name, 10 * tenth)

    with StandBus(experiment.stand or experiment.motor, BusConfig("virtual", DEMO_CHANNEL),
                  seed=experiment.seed, **SIMULATED_MASTER_OPTIONS) as bus:
        result = StandController(bus, "lockstep", progress=progress).run_experiment(experiment, out)
    log.info("  %s: %d run(s), %.1f s of stand time in %.1f s", experiment.name, len(result.runs),
             sum(r.stand_time_s for r in result.runs), time.monotonic() - started)
    if not result.complete:
        raise InputError(f"{experiment.name}: incomplete runs on the virtual bus: "
                         f"{[(r.name, r.samples, r.aborted) for r in result.runs]}")
    return result


def _diagnosis_runs(out: Path, motor_name: str, period_s: float) -> list[Any]:
    """Two reversing band-limited speed runs over the bus: TRAIN and HOLDOUT."""
    from bus.adapters import BusConfig
    from bus.stand_bus import StandBus
    from stand.controller import StandController, drive_setup
    from stand.procedures import PortCommand, Procedure, multisine
    from stand.profiles import load_motor

    motor = load_motor(motor_name)
    drive = drive_setup(motor, motor.drive.node_id, "speed")
    samples = int(round(DIAGNOSIS_DURATION_S / period_s))
    records = []
    with StandBus(motor_name, BusConfig("virtual", DEMO_CHANNEL), seed=DIAGNOSIS_SEED,
                  **SIMULATED_MASTER_OPTIONS) as bus:
        controller = StandController(bus, "lockstep")
        for k, name in enumerate(("train", "holdout")):
            command = multisine(samples, period_s, 0.0,
                                DIAGNOSIS_SPEED_FRACTION * motor.limits.speed_rad_s,
                                DIAGNOSIS_BAND_HZ, seed=DIAGNOSIS_SEED + k)
            procedure = Procedure(f"diagnosis_{name}", period_s, (PortCommand("speed", command),),
                                  description="band-limited speed command around standstill")
            records.append(controller.run_procedure(procedure, [drive], out))
    log.info("  diagnosis runs: %d x %.1f s", len(records), DIAGNOSIS_DURATION_S)
    return records


def run(args: argparse.Namespace) -> dict[str, Any]:
    from stand.diagnosis import diagnose
    from stand.ident.efficiency import efficiency
    from stand.ident.supply import motor_supply
    from stand.ident.torque_constant import torque_constant
    from stand.profiles import load_motor, load_stand
    from stand.runfile import read_run
    from stand.storage import Storage

    if args.repeats < 2:
        raise InputError(f"--repeats must be >= 2 (one no-load run trains, another is the "
                         f"holdout), got {args.repeats}")
    if not 0 < args.duration <= 60:
        raise InputError(f"--duration must be in (0, 60] s, got {args.duration}")
    for noisy in ("canopen", "can"):
        logging.getLogger(noisy).setLevel(logging.WARNING)
    settings = get_settings()
    out = Path(args.output) if args.output else settings.data_dir / "demo"
    started = time.monotonic()
    log.info("stand demo: simulated drives on the virtual CAN bus, output in %s", out)

    tc_exp = _experiment("seed000_torque_constant", repeats=args.repeats, duration_s=args.duration)
    tc = _run_experiment(tc_exp, out / "torque_constant")
    eff_exp = _experiment("seed000_efficiency")
    eff = _run_experiment(eff_exp, out / "efficiency")

    no_load = [read_run(r.path, "single") for r in tc.runs if r.name.startswith("no_load")]
    loaded = [read_run(r.path, "single") for r in tc.runs if r.name.startswith("added_inertia")]
    stand = load_stand(eff_exp.stand)
    k_in, k_out = (load_motor(m).motor.Kt for m in (stand.motor_in, stand.motor_out))
    # the lab's motor profile tells the identification the drive (its speed loop's gains
    # bound what the period-mean current can miss), as `stand torque-constant --motor` does
    kt = torque_constant(no_load, loaded, tc_exp.added_inertia_kgm2,
                         supply=motor_supply(str(tc_exp.motor)))
    eta = efficiency(read_run(eff.runs[0].path, "reducer"), stand.reducer.ratio, k_in, k_out)
    log.info("  torque constant and efficiency identified")
    diag = _diagnosis_runs(out / "diagnosis", str(tc_exp.motor), float(tc_exp.period_s or 1e-3))
    train, holdout = (read_run(r.path, "single") for r in diag)
    try:
        diagnosis: Any = diagnose(train, holdout, kt=kt.Kt)
        gap, verdict = diagnosis.gap_percent, diagnosis.verdict
    except InputError as exc:
        diagnosis, gap, verdict = {"refused": str(exc)}, None, f"refused: {exc}"
    log.info("  diagnosis done")

    storage = Storage(settings.database)
    try:
        ids = {r.name: storage.store_run(read_run(r.path, r.kind), r.kind, "job",
                                         {"demo": r.name, "path": r.path}).id
               for r in (*tc.runs, *eff.runs, *diag)}
        storage.add_result("torque-constant", {"no_load": [ids[r.name] for r in tc.runs
                                                           if r.name.startswith("no_load")],
                                               "loaded": [ids[r.name] for r in tc.runs
                                                          if r.name.startswith("added_inertia")],
                                               "motor": str(tc_exp.motor)},
                           to_jsonable(kt))
        if gap is not None:
            storage.add_result("diagnose", {"train": ids["diagnosis_train"],
                                            "holdout": ids["diagnosis_holdout"], "kt": kt.Kt},
                               to_jsonable(diagnosis))
        storage.add_result("efficiency", {"run": ids[eff.runs[0].name], "ratio": stand.reducer.ratio,
                                          "k_in": k_in, "k_out": k_out}, to_jsonable(eta))
    finally:
        storage.close()

    plots = [] if args.no_plots else _plots(out, kt, eta, no_load[0], loaded[0],
                                            read_run(eff.runs[0].path, "reducer"))
    return {
        "Kt": kt.Kt, "Kt_std": kt.Kt_std, "Kt_profile": load_motor(stand.motor_in).motor.Kt,
        "efficiency": eta.efficiency, "efficiency_std": eta.efficiency_std,
        "efficiency_profile": stand.reducer.efficiency,
        "gap_percent": gap, "verdict": verdict, "diagnosis": to_jsonable(diagnosis),
        "output_dir": str(out), "database": str(settings.database),
        "run_files": [r.path for r in (*tc.runs, *eff.runs, *diag)],
        "traces": [r.trace_path for r in (*tc.runs, *eff.runs, *diag)],
        "plots": plots, "wall_time_s": time.monotonic() - started,
    }


def _plots(out: Path, kt: Any, eta: Any, no_load: Any, loaded: Any, reducer: Any) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 5))
    for run, label in ((no_load, "no load"), (loaded, "added inertia")):
        axes[0].plot(run.time_s, run["velocity_rad_s"] if "velocity_rad_s" in run else
                     run["position_rad"], label=label, lw=0.8)
        axes[1].plot(run.time_s, run["current_A"], label=label, lw=0.8)
    axes[0].set_ylabel("velocity, rad/s")
    axes[1].set_ylabel("current, A")
    axes[1].set_xlabel("time, s")
    axes[0].legend(fontsize=8)
    axes[1].legend(fontsize=8)
    fig.suptitle("seed 000 identification runs over the virtual CAN bus\n"
                 f"result: Kt = {kt.Kt:.5f} ± {kt.Kt_std:.5f} N·m/A, J = {kt.J:.4g} kg·m², "
                 f"no-load current {kt.no_load_current_A:.3f} A", fontsize=10)
    paths.append(out / "identification_runs.png")
    fig.savefig(paths[-1], dpi=100, bbox_inches="tight")
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.plot(reducer.time_s, reducer["current_in_A"], label="input motor", lw=0.8)
    ax.plot(reducer.time_s, reducer["current_out_A"], label="output motor (load)", lw=0.8)
    ax.set_xlabel("time, s")
    ax.set_ylabel("current, A")
    ax.legend(fontsize=8)
    fig.suptitle("two-motor efficiency run: output load steps\n"
                 f"result: efficiency {eta.efficiency:.4f} ± {eta.efficiency_std:.4f}", fontsize=10)
    paths.append(out / "efficiency_run.png")
    fig.savefig(paths[-1], dpi=100, bbox_inches="tight")  # the x-label is kept whole
    plt.close(fig)
    return [str(p) for p in paths]


def summarize(result: dict[str, Any]) -> str:
    kt, eta = result["Kt"], result["efficiency"]
    lines = [
        f"torque constant Kt = {kt:.5f} ± {result['Kt_std']:.5f} N·m/A "
        f"(simulated motor: {result['Kt_profile']:.5f})",
        f"reducer efficiency = {eta:.4f} ± {result['efficiency_std']:.4f} "
        f"(simulated reducer: {result['efficiency_profile']:.2f})",
        "sim-to-real gap: " + (f"{result['gap_percent']:.2f} % of holdout velocity RMS, verdict: "
                               f"{result['verdict']}" if result["gap_percent"] is not None
                               else str(result["verdict"])),
        f"run files and CAN traces: {result['output_dir']} ({len(result['run_files'])} runs)",
        f"plots: {', '.join(result['plots']) or 'skipped'}",
        f"stored in {result['database']} (see `stand serve`, GET /runs and /results)",
        f"done in {result['wall_time_s']:.1f} s",
    ]
    return "\n".join(lines)
