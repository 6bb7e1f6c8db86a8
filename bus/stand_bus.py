"""The stand's bus as the controller sees it: a master, plus simulated drives if wanted.

:class:`StandBus` is the small interface :class:`stand.controller.StandController` talks
to (it never imports ``can``): ``setup``, ``run``, ``quick_stop_all``, ``stop_drives``,
``status``, ``close``. With ``simulate=True`` (the default on the ``virtual`` interface)
the drives of the profile are simulated in this process on the same bus.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bus.adapters import BusConfig
from bus.drive import DriveConfig
from bus.eds import Scaling
from bus.master import Master
from bus.run_loop import ChunkCallback, ProgressCallback
from bus.sampler import Samples
from bus.simstand import SimStand
from stand.bus_interface import DriveSetup
from stand.errors import InputError


class StandBus:
    """A master on ``config``'s bus and, with ``simulate``, the simulated drives of ``profile``.

    Parameters
    ----------
    profile : str
        Motor or stand profile whose drives are simulated (ignored without ``simulate``).
    config : BusConfig or None
        The bus (default: from the settings).
    simulate : bool or None
        Simulate the drives in this process; None: only on the ``virtual`` interface.
    seed : int or None
        Seed of the simulated sensor noise.
    eds : path or None
        EDS or DCF of every drive that has none of its own (a real drive's, from its
        vendor); default: the simulated drive's. Each device is checked against it.
    master_options : dict
        Keyword arguments of :class:`~bus.master.Master` (timeouts).
    """

    def __init__(self, profile: str | None = None, config: BusConfig | None = None,
                 simulate: bool | None = None, seed: int | None = None,
                 eds: str | Path | None = None, **master_options: Any) -> None:
        self.config = config or BusConfig.from_settings()
        self.eds = eds
        if simulate is None:
            simulate = self.config.interface == "virtual"
        self.sim: SimStand | None = None
        if simulate:
            if profile is None:
                raise InputError("StandBus: simulate=True needs a profile to simulate the drives")
            self.sim = SimStand(profile, self.config, seed)
        try:
            self.master = Master(self.config, **master_options)
        except Exception:
            if self.sim is not None:
                self.sim.close()
            raise

    def setup(self, drives: Sequence[DriveSetup], period_s: float,
              added_inertia_kgm2: float | None = None, time_mode: str = "lockstep",
              trace_path: str | Path | None = None) -> None:
        configs = [DriveConfig(d.node_id, d.mode,
                               Scaling(d.counts_per_rev, d.rated_current_A,
                                       current_mean_unit_A=d.current_mean_unit_A),
                               d.eds or self.eds, current_mean=d.current_mean)
                   for d in drives]
        self.master.setup(configs, period_s, added_inertia_kgm2, time_mode, trace_path)

    def run(self, targets: np.ndarray, *, time_mode: str = "lockstep",
            on_chunk: ChunkCallback | None = None, chunk_samples: int = 1000,
            stop: threading.Event | None = None, progress: ProgressCallback | None = None,
            trace_path: str | Path | None = None) -> Samples:
        return self.master.run(targets, time_mode=time_mode, on_chunk=on_chunk,
                               chunk_samples=chunk_samples, stop=stop, progress=progress,
                               trace_path=trace_path)

    def quick_stop_all(self) -> None:
        self.master.quick_stop_all()

    def stop_drives(self) -> None:
        self.master.stop_drives()

    def status(self) -> dict[str, Any]:
        status = self.master.status()
        status["simulated"] = self.sim is not None
        return status

    def close(self) -> None:
        try:
            self.master.close()
        finally:
            if self.sim is not None:
                self.sim.close()

    def __enter__(self) -> StandBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
