"""The stand controller: runs an experiment profile over the bus and writes run files.

An experiment profile (``profiles/experiments/*.yaml``) names a procedure of
:mod:`stand.procedures` (seed 000: the no-load and added-inertia runs, the two-motor
efficiency run; seed 001: the voltage step) and the motor or stand it runs on. The
controller checks every command of every run against the profile's limits before anything
is sent (:class:`~stand.errors.LimitError`), then for each run: resets and enables the
drives, sends the command sequence one sample per SYNC, records, and stops the drives
safely (quick stop, then disable). It never imports ``can``: it talks to a
:class:`StandBus` (``bus.stand_bus.StandBus`` implements it).

Callbacks for a caller such as the HTTP service: ``progress(fraction)`` while it runs,
``on_chunk(columns)`` with the newly recorded rows of the current run (run-file columns)
so they can be persisted as they arrive, a ``threading.Event`` to stop, and
:meth:`StandController.quick_stop_all` / :meth:`StandController.status`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from stand.bus_interface import DriveSamples, Samples, StandBus
from stand.errors import BusError, LimitError, ProfileError, RunAborted
from stand.excitation import excitation
from stand.procedures import (
    SEED_ADDED_INERTIA_KGM2,
    PortCommand,
    Procedure,
    diagnosis_procedures,
    efficiency_procedure,
    torque_constant_procedures,
)
from stand.profiles import (
    PROFILES_DIR,
    MotorProfile,
    load_motor,
    load_stand,
    read_profile,
    resolve,
    validate,
)
from stand.runfile import CURRENT_MEAN_COLUMN, check_columns, format_run, write_run

log = logging.getLogger(__name__)

#: Counts per revolution a drive reports for a motor without an encoder.
FINE_COUNTS_PER_REV = 1 << 20
#: Rows handed to ``on_chunk`` at a time.
CHUNK_SAMPLES = 500
#: Trace format (python-can candump log) next to each run file.
TRACE_SUFFIX = ".log"
MIN_RUN_SAMPLES = 20


class ExperimentProfile(BaseModel):
    """An experiment: which procedure, on which motor or stand, how long, how often."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str
    description: str = ""
    procedure: Literal["torque_constant", "no_load", "added_inertia", "efficiency", "voltage_step",
                       "diagnosis"]
    motor: str | None = Field(None, description="motor profile (single-motor procedures)")
    stand: str | None = Field(None, description="stand profile (efficiency)")
    repeats: int = Field(5, ge=1, le=100)
    duration_s: float = Field(10.0, gt=0, le=3600)
    period_s: float | None = Field(None, gt=0, description="SYNC period, s (default: profile)")
    added_inertia_kgm2: float = Field(SEED_ADDED_INERTIA_KGM2, gt=0)
    load_current_A: float = Field(0.5, gt=0)
    step_V: float = Field(6.0, description="voltage step height, V")
    step_time_s: float = Field(0.5, ge=0)
    seed: int = 0


def load_experiment(name_or_path: str | Path) -> ExperimentProfile:
    """Load and validate ``profiles/experiments/<name>.yaml`` (or a path)."""
    path = resolve(name_or_path, "experiments")
    return validate(ExperimentProfile, read_profile(path), path)


@dataclass(frozen=True)
class DriveSetup:
    """One drive of a run, as the bus needs it (plain data; see ``bus.drive.DriveConfig``)."""

    node_id: int
    mode: str
    counts_per_rev: int
    rated_current_A: float
    eds: str | None = None
    limits: Any = None
    #: The drive's object holding its current averaged over each SYNC period, (index,
    #: subindex), and A per count of it (None: per mille of the rated current, as 0x6078);
    #: the motor profile's ``drive.current_mean_object`` and ``current_mean_unit_A``.
    current_mean: tuple[int, int] | None = None
    current_mean_unit_A: float | None = None


@dataclass
class RunResult:
    """One recorded run."""

    name: str
    kind: str
    path: str | None
    trace_path: str | None
    samples: int
    expected_samples: int
    period_s: float
    complete: bool
    lost: dict[int, int]
    duplicates: dict[int, int]
    late: dict[int, int]
    aborted: str | None = None
    #: Samples whose targets reached the drives a SYNC late (real time, kernel SYNC).
    late_targets: int = 0
    wall_time_s: float = 0.0
    stand_time_s: float = 0.0
    description: str = ""


@dataclass
class ExperimentResult:
    """All runs of an experiment profile."""

    name: str
    procedure: str
    runs: list[RunResult] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        return all(r.complete for r in self.runs)


def drive_setup(profile: MotorProfile, node_id: int, mode: str) -> DriveSetup:
    """The drive of ``profile``'s motor at ``node_id``, commanded in ``mode``."""
    counts = profile.sensor_params().counts_per_rev or FINE_COUNTS_PER_REV
    return DriveSetup(node_id, mode, counts, profile.drive.rated_current_A, limits=profile.limits,
                      current_mean=profile.drive.current_mean(),
                      current_mean_unit_A=profile.drive.current_mean_unit_A)


def voltage_step_procedure(profile: MotorProfile, step_V: float, duration_s: float,
                           period_s: float, step_time_s: float) -> Procedure:
    """Seed 001 §2: a voltage step of ``step_V`` at ``step_time_s`` on a resting motor."""
    samples = int(round(duration_s / period_s))
    command = excitation("step", samples, period_s, step_V, 0.0, 1, step_time_s)
    return Procedure("voltage_step", period_s, (PortCommand("voltage", command),), kind="step",
                     description=f"voltage step of {step_V} V at {step_time_s} s")


def plan(experiment: ExperimentProfile) -> list[tuple[Procedure, list[DriveSetup]]]:
    """The runs of ``experiment`` with their drives; every command checked against the limits."""
    e = experiment
    runs: list[tuple[Procedure, list[DriveSetup]]] = []
    if e.procedure == "efficiency":
        if not e.stand:
            raise ProfileError(f"experiment {e.name}: procedure efficiency needs 'stand'")
        stand = load_stand(e.stand)
        m_in, m_out = load_motor(stand.motor_in), load_motor(stand.motor_out)
        proc = efficiency_procedure(stand, m_in, e.load_current_A, e.duration_s, e.period_s)
        runs.append((proc, [drive_setup(m_in, stand.node_in, proc.commands[0].mode),
                            drive_setup(m_out, stand.node_out, proc.commands[1].mode)]))
    else:
        if not e.motor:
            raise ProfileError(f"experiment {e.name}: procedure {e.procedure} needs 'motor'")
        motor = load_motor(e.motor)
        period = e.period_s or motor.sample_period_s
        if e.procedure == "voltage_step":
            if e.step_time_s >= e.duration_s:
                raise ProfileError(f"experiment {e.name}: step_time_s {e.step_time_s} s must lie "
                                   f"within the run's duration_s {e.duration_s} s")
            procs = [voltage_step_procedure(motor, e.step_V, e.duration_s, period, e.step_time_s)]
        elif e.procedure == "diagnosis":
            procs = diagnosis_procedures(motor, e.repeats, period, e.duration_s, e.seed)
        else:
            no_load, loaded = torque_constant_procedures(
                motor, e.repeats, period, e.duration_s, e.added_inertia_kgm2, e.seed)
            pairs = {"torque_constant": [p for pair in zip(no_load, loaded, strict=True) for p in pair],
                     "no_load": no_load, "added_inertia": loaded}
            procs = pairs[e.procedure]
        runs += [(p, [drive_setup(motor, motor.drive.node_id, p.commands[0].mode)]) for p in procs]
    for proc, drives in runs:
        check_limits(proc, drives)
    return runs


def check_limits(procedure: Procedure, drives: Sequence[DriveSetup]) -> None:
    """Raise :class:`LimitError` if any command of ``procedure`` exceeds its drive's limits."""
    for port, drive in zip(procedure.commands, drives, strict=True):
        limits = drive.limits
        limit = {"speed": limits.speed_rad_s, "current": limits.current_A,
                 "voltage": limits.voltage_V}[port.mode]
        peak = float(np.max(np.abs(port.values))) if len(port.values) else 0.0
        if not np.all(np.isfinite(port.values)) or peak > limit:
            unit = {"speed": "rad/s", "current": "A", "voltage": "V"}[port.mode]
            raise LimitError(f"run {procedure.name}, node {drive.node_id}: {port.mode} command reaches "
                             f"{peak:.4g} {unit}, beyond the profile's limit {limit:.4g} {unit}; "
                             "nothing was sent")


def run_columns(kind: str, samples: Samples, start: int = 0,
                stop: int | None = None) -> dict[str, np.ndarray]:
    """Run-file columns (CONTRACT §1) of the bus samples ``start:stop``, gaps left out.

    A single-motor run in speed mode has ``speed_target_rad_s``: the target velocity the
    drive was sent for each sample's period, as it went over the bus; ``current_mean_A``
    where the drive reports its current averaged over each period (the simulated drive's
    0x2002)."""
    stop = samples.count if stop is None else stop
    rows = slice(start, stop)
    drives = samples.drives
    valid = np.ones(stop - start, dtype=bool)
    for d in drives:
        valid &= d.valid[rows]
    out: dict[str, np.ndarray] = {"time_s": (np.arange(start, stop) * samples.period_s)[valid]}

    def col(d: DriveSamples, name: str) -> np.ndarray | None:
        values = d.columns.get(name)
        return None if values is None else values[rows][valid]

    names = {"single": [("current_A", "current_A"), ("position_rad", "position_rad"),
                        ("velocity_rad_s", "velocity_rad_s"), ("voltage_V", "voltage_V"),
                        ("speed_target_rad_s", "speed_target_rad_s"),
                        (CURRENT_MEAN_COLUMN, "current_mean_A")],
             "step": [("voltage_V", "voltage_V"), ("velocity_rad_s", "velocity_rad_s"),
                      ("current_A", "current_A"), ("position_rad", "position_rad")]}
    if kind == "reducer":
        for suffix, d in zip(("in", "out"), drives, strict=True):
            for name, unit in (("current", "A"), ("position", "rad"), ("voltage", "V")):
                values = col(d, f"{name}_{unit}" if name != "voltage" else "voltage_V")
                if values is not None:
                    out[f"{name}_{suffix}_{unit}"] = values
        return out
    for column, name in names[kind]:
        values = col(drives[0], name)
        if values is not None:
            out[column] = values
    return out


class StandController:
    """Runs experiments over ``bus``.

    Parameters
    ----------
    bus : StandBus
        The stand's bus (``bus.stand_bus.StandBus``).
    time_mode : {'lockstep', 'realtime'}
        Lockstep for simulated drives, real time for hardware.
    progress : callable or None
        ``progress(fraction)`` of the whole experiment, 0..1.
    on_chunk : callable or None
        ``on_chunk(columns)``: new rows of the current run, run-file columns.
    stop : threading.Event or None
        Set it to stop; the drives are quick-stopped and the samples so far kept.
    trace_suffix : {'.log', '.asc', '.blf'}
        Format of each run's raw trace (candump, Vector ASCII, Vector binary).
    """

    def __init__(self, bus: StandBus, time_mode: str = "lockstep",
                 progress: Callable[[float], None] | None = None,
                 on_chunk: Callable[[Mapping[str, np.ndarray]], None] | None = None,
                 stop: threading.Event | None = None, chunk_samples: int = CHUNK_SAMPLES,
                 trace_suffix: str = TRACE_SUFFIX) -> None:
        self.bus = bus
        self.trace_suffix = trace_suffix
        self.time_mode = time_mode
        self.progress = progress
        self.on_chunk = on_chunk
        self.stop = stop or threading.Event()
        self.chunk_samples = chunk_samples
        self.current: dict[str, Any] = {}

    def quick_stop_all(self) -> None:
        """CiA 402 quick stop to every drive at once; a running experiment ends."""
        self.stop.set()
        self.bus.quick_stop_all()

    def status(self) -> dict[str, Any]:
        """The bus's status (nodes, NMT states, heartbeat ages, counters) and the current run."""
        return {**self.bus.status(), "run": dict(self.current)}

    def run_experiment(self, experiment: ExperimentProfile | str,
                       out_dir: str | Path | None) -> ExperimentResult:
        """Run every run of ``experiment``; write ``<run>.csv`` and its trace to ``out_dir``."""
        if isinstance(experiment, str):
            experiment = load_experiment(experiment)
        runs = plan(experiment)  # limits checked for all runs before anything moves
        result = ExperimentResult(experiment.name, experiment.procedure)
        total = sum(p.samples for p, _ in runs)
        done = 0
        for procedure, drives in runs:
            offset = done

            def fraction(k: int, n: int, offset: int = offset) -> None:
                if self.progress is not None:
                    self.progress((offset + k) / total)

            record = self.run_procedure(procedure, drives, out_dir, fraction)
            result.runs.append(record)
            done += procedure.samples
            if record.aborted:
                break
        return result

    def run_procedure(self, procedure: Procedure, drives: Sequence[DriveSetup],
                      out_dir: str | Path | None,
                      progress: Callable[[int, int], None] | None = None) -> RunResult:
        """One run: set up the drives, send the commands one per SYNC, record, stop safely."""
        check_limits(procedure, drives)
        out = Path(out_dir) if out_dir is not None else None
        trace = str(out / f"{procedure.name}{self.trace_suffix}") if out is not None else None
        self.current = {"name": procedure.name, "samples": procedure.samples, "done": 0}
        targets = np.vstack([port.values for port in procedure.commands])

        def on_progress(k: int, n: int) -> None:
            self.current["done"] = k
            if progress is not None:
                progress(k, n)

        def on_chunk(samples: Samples, start: int, stop: int) -> None:
            if self.on_chunk is not None:
                self.on_chunk(run_columns(procedure.kind, samples, start, stop))

        if out is not None:
            out.mkdir(parents=True, exist_ok=True)
        started = time.monotonic()
        # The trace starts before the setup, so it holds what its frames mean (mappings,
        # cycle period, units) and reads back without being told.
        self.bus.setup(drives, procedure.sample_period_s, procedure.added_inertia_kgm2,
                       self.time_mode, trace_path=trace)
        try:
            samples = self.bus.run(targets, time_mode=self.time_mode, on_chunk=on_chunk,
                                   chunk_samples=self.chunk_samples, stop=self.stop,
                                   progress=on_progress, trace_path=trace)
        finally:
            try:
                self.bus.stop_drives()
            except BusError as exc:
                log.warning("stopping the drives after run %s: %s", procedure.name, exc)
        wall = time.monotonic() - started
        record = self._write(procedure, samples, out, trace, wall)
        error = samples.error
        if error is not None:
            raise RunAborted(f"run {procedure.name} aborted after {samples.count} of "
                             f"{procedure.samples} samples: {error}; samples so far kept"
                             + (f" in {record.path}" if record.path else "")) from error
        return record

    def _write(self, procedure: Procedure, samples: Samples, out: Path | None, trace: str | None,
               wall_s: float) -> RunResult:
        columns = run_columns(procedure.kind, samples)
        path = None
        if out is not None and len(columns["time_s"]):
            target = out / f"{procedure.name}.csv"
            if samples.complete and len(columns["time_s"]) >= MIN_RUN_SAMPLES:
                check_columns(columns, procedure.kind, str(target))  # type: ignore[arg-type]
                path = str(write_run(target, columns))
            else:  # gaps or an early end: written as recorded, the result says so
                target.write_text(format_run(columns), encoding="utf-8")
                path = str(target)
        ids = [d.node_id for d in samples.drives]
        return RunResult(
            name=procedure.name, kind=procedure.kind, path=path, trace_path=trace,
            samples=int(samples.count), expected_samples=procedure.samples,
            period_s=procedure.sample_period_s,
            complete=bool(samples.complete and samples.count == procedure.samples),
            lost=dict(zip(ids, (d.lost for d in samples.drives), strict=True)),
            duplicates=dict(zip(ids, (d.duplicates for d in samples.drives), strict=True)),
            late=dict(zip(ids, (d.late for d in samples.drives), strict=True)),
            aborted=samples.aborted, late_targets=int(samples.late_targets), wall_time_s=wall_s,
            stand_time_s=samples.count * procedure.sample_period_s,
            description=procedure.description)


#: Where experiment profiles live.
EXPERIMENTS_DIR = PROFILES_DIR / "experiments"
