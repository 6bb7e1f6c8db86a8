"""What runs an experiment on the stand for the job queue: the :class:`StandRunner`
protocol, the plans and outcomes it trades with :class:`~stand.jobs.JobManager`, and
:class:`ControllerRunner`, the stand controller over the bus.

A request names a shipped experiment profile and overrides of its fields; it is checked
against the profile's limits when planned, before anything moves.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from stand.errors import InputError, NotFoundError

#: Most samples one run may record (duration_s / period_s), checked before planning:
#: planning holds every command in memory (about 25 bytes a sample), so 10**8 samples
#: would take seconds and gigabytes before any limit check. Two million is 2000 s at 1 kHz.
MAX_RUN_SAMPLES = 2_000_000

#: Master timeouts for drives simulated in this process (``bus.master.Master`` options).
#: The simulated drives share the CPU with the master and the service (and, on a build
#: machine, with everything else); under load a 100 ms heartbeat or a 0.5 s PDO answer is
#: missed although no drive failed and no frame was lost. Real drives keep the defaults.
SIMULATED_MASTER_OPTIONS: dict[str, Any] = {"heartbeat_period_s": 1.0, "pdo_timeout_s": 5.0}

ProgressCallback = Callable[[float], None]
ChunkCallback = Callable[[Mapping[str, np.ndarray]], None]


@dataclass(frozen=True)
class RunPlan:
    """One checked run of a request: its kind, its profile, the request as stored, and
    what the runner needs to execute it (``payload``, not stored)."""

    kind: str
    profile: str
    request: dict[str, Any]
    payload: Any = None


@dataclass
class RunOutcome:
    """What a runner reports at the end of a run."""

    meta: dict[str, Any] = field(default_factory=dict)
    message: str = ""


class StandRunner(Protocol):
    """What the job manager needs from a stand (bus controller or simulation)."""

    def plan(self, request: Mapping[str, Any]) -> list[RunPlan]:
        """The runs of ``request``, checked against the profile and its limits; nothing moves."""
        ...

    def execute(self, run_id: str, plan: RunPlan, on_progress: ProgressCallback, on_chunk: ChunkCallback,
                stop: threading.Event) -> RunOutcome:
        """Run the experiment; return when done or when ``stop`` is set."""
        ...

    def quick_stop_all(self) -> dict[str, Any]:
        """CiA 402 quick stop to every drive at once."""
        ...

    def status(self) -> dict[str, Any]:
        """Nodes, NMT states, heartbeat ages, error counters."""
        ...

    def close(self) -> None:
        """Release the bus and threads."""
        ...


def _check_samples(experiment: Any) -> None:
    """Refuse a run of more than :data:`MAX_RUN_SAMPLES` samples before it is planned."""
    from stand.profiles import load_motor, load_stand

    period = experiment.period_s
    if period is None and experiment.stand:
        period = load_stand(experiment.stand).sample_period_s
    elif period is None and experiment.motor:
        period = load_motor(experiment.motor).sample_period_s
    if period is None:
        return  # plan() names the missing motor or stand
    samples = experiment.duration_s / period
    if not samples <= MAX_RUN_SAMPLES:
        raise InputError(f"overrides: duration_s {experiment.duration_s:g} s at period_s "
                         f"{period:g} s is {samples:.3g} samples a run, more than "
                         f"{MAX_RUN_SAMPLES}; shorten duration_s or lengthen period_s")


class ControllerRunner:
    """The stand run by :class:`stand.controller.StandController` over the bus.

    A request names an experiment profile (``profiles/experiments``) and ``overrides``
    of its fields (``procedure``, ``repeats``, ``duration_s``, ``seed``, ...; never the
    motor or stand, whose profiles hold the limits); it becomes one job per
    run of the experiment (the torque-constant experiment: no-load and added-inertia
    runs, alternately). Run files and CAN traces go to ``runs_dir/<run id>/``.

    Parameters
    ----------
    bus_factory : callable
        ``bus_factory(profile, seed)`` opens the stand's bus (a ``StandBus``), with the
        drives of the motor or stand ``profile`` simulated when the bus is virtual.
    runs_dir : path
        Where run files and traces are written.
    time_mode : {'lockstep', 'realtime'}
        SYNC timing (lockstep for simulated drives).
    """

    def __init__(self, bus_factory: Callable[[str, int | None], Any], runs_dir: str | Path,
                 time_mode: str = "lockstep") -> None:
        self.bus_factory = bus_factory
        self.runs_dir = Path(runs_dir)
        self.time_mode = time_mode
        self._lock = threading.Lock()
        self._bus: Any = None
        self._bus_key: tuple[str, int | None] | None = None

    def plan(self, request: Mapping[str, Any]) -> list[RunPlan]:
        """The runs of ``request``; ``profile`` is a shipped experiment's *name*.

        Requests come from the network: a path would read any YAML file on this machine
        and tell the caller whether it exists, so only the names of the shipped experiment profiles count.
        """
        from pydantic import ValidationError

        from stand.controller import ExperimentProfile, load_experiment, plan
        from stand.profiles import describe, list_profiles

        name = str(request.get("profile"))
        known = list_profiles().get("experiments", [])
        if name not in known:
            raise NotFoundError(f"profile: no experiment profile of that name; known: "
                                f"{', '.join(known)}")
        experiment = load_experiment(name)
        overrides = dict(request.get("overrides") or {})
        for key in ("name", "motor", "stand"):
            if key in overrides:
                raise InputError(f"overrides.{key}: cannot be changed by a request; choose another "
                                 "of the shipped experiment profiles")
        try:
            experiment = ExperimentProfile(**{**experiment.model_dump(), **overrides})
        except ValidationError as exc:
            raise InputError(describe(exc, "overrides.", echo=False)) from exc
        _check_samples(experiment)
        runs = plan(experiment)  # LimitError before anything moves
        target = str(experiment.stand or experiment.motor)
        return [RunPlan(proc.kind, experiment.name,
                        {"profile": name, "overrides": overrides, "procedure": proc.name,
                         "run": k + 1, "runs": len(runs), "description": proc.description},
                        payload=(proc, drives, target, experiment.seed))
                for k, (proc, drives) in enumerate(runs)]

    def _open(self, profile: str, seed: int | None) -> Any:
        with self._lock:
            if self._bus is not None and self._bus_key == (profile, seed):
                return self._bus
            old, self._bus, self._bus_key = self._bus, None, None
        if old is not None:
            old.close()
        bus = self.bus_factory(profile, seed)
        with self._lock:
            self._bus, self._bus_key = bus, (profile, seed)
        return bus

    def execute(self, run_id: str, plan: RunPlan, on_progress: ProgressCallback,
                on_chunk: ChunkCallback, stop: threading.Event) -> RunOutcome:
        from stand.controller import StandController

        procedure, drives, target, seed = plan.payload
        bus = self._open(target, seed)
        controller = StandController(bus, self.time_mode, on_chunk=on_chunk, stop=stop)
        record = controller.run_procedure(procedure, drives, self.runs_dir / run_id,
                                          lambda k, n: on_progress(k / n))
        meta = {"path": record.path, "trace_path": record.trace_path,
                "expected_samples": record.expected_samples, "period_s": record.period_s,
                "complete": record.complete, "lost": record.lost, "late": record.late,
                "duplicates": record.duplicates, "wall_time_s": record.wall_time_s,
                "stand_time_s": record.stand_time_s, "aborted": record.aborted}
        return RunOutcome(meta, record.aborted or "")

    def quick_stop_all(self) -> dict[str, Any]:
        with self._lock:
            bus = self._bus
        if bus is None:
            return {"sent": False, "reason": "no bus open: no drive has been set up yet"}
        bus.quick_stop_all()
        return {"sent": True, "nodes": [n["node_id"] for n in bus.status().get("nodes", [])]}

    def status(self) -> dict[str, Any]:
        with self._lock:
            bus, key = self._bus, self._bus_key
        if bus is None:
            return {"bus": "closed (opens with the first run)", "nodes": []}
        return {**bus.status(), "profile": key[0] if key else None}

    def close(self) -> None:
        with self._lock:
            bus, self._bus, self._bus_key = self._bus, None, None
        if bus is not None:
            bus.close()
