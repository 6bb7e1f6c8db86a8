"""What the stand controller needs of a bus, as protocols: it never imports ``can``.

``bus.stand_bus.StandBus`` implements :class:`StandBus`; what its ``run`` returns
(``bus.sampler.Samples``) implements :class:`Samples`. The controller and the procedures
are written against these, so a bus of another kind (a vendor's API, a replay of a trace)
only has to provide the same few members.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np


class DriveSamples(Protocol):
    """The samples of one drive in SI units; NaN where a TPDO was lost."""

    @property
    def node_id(self) -> int: ...
    @property
    def columns(self) -> Mapping[str, np.ndarray]: ...
    @property
    def lost(self) -> int: ...
    @property
    def duplicates(self) -> int: ...
    @property
    def late(self) -> int: ...
    @property
    def valid(self) -> np.ndarray:
        """True for the samples whose every TPDO arrived, once and in time."""
        ...


class Samples(Protocol):
    """What a run recorded: SYNC-aligned samples of every drive.

    ``period_s`` is the SYNC period (s; sample k is at ``k·period_s`` of stand time),
    ``count`` the windows recorded, ``aborted`` why the run ended early (or None), and
    ``error`` the error that ended it, if any.
    """

    @property
    def period_s(self) -> float: ...
    @property
    def count(self) -> int: ...
    @property
    def drives(self) -> Sequence[DriveSamples]: ...
    @property
    def aborted(self) -> str | None: ...
    @property
    def error(self) -> Exception | None: ...
    @property
    def late_targets(self) -> int:
        """Windows whose targets reached the drives after their SYNC (a SYNC late)."""
        ...
    @property
    def complete(self) -> bool: ...


class DriveSetup(Protocol):
    """One drive of a run as the bus needs it."""

    @property
    def node_id(self) -> int: ...
    @property
    def mode(self) -> str: ...
    @property
    def counts_per_rev(self) -> int: ...
    @property
    def rated_current_A(self) -> float: ...
    @property
    def eds(self) -> str | None: ...
    @property
    def current_mean(self) -> tuple[int, int] | None: ...
    @property
    def current_mean_unit_A(self) -> float | None: ...


ChunkCallback = Callable[[Samples, int, int], None]
ProgressCallback = Callable[[int, int], None]


class StandBus(Protocol):
    """A bus with drives on it: set them up, run a command sequence, stop them.

    A ``trace_path`` given to ``setup`` starts the trace there, and the ``run`` that follows
    goes on writing it (given the same file or none)."""

    def setup(self, drives: Sequence[DriveSetup], period_s: float,
              added_inertia_kgm2: float | None = None, time_mode: str = ...,
              trace_path: str | Path | None = ...) -> None: ...
    def run(self, targets: np.ndarray, *, time_mode: str = ..., on_chunk: ChunkCallback | None = ...,
            chunk_samples: int = ..., stop: threading.Event | None = ...,
            progress: ProgressCallback | None = ..., trace_path: str | Path | None = ...) -> Samples: ...
    def quick_stop_all(self) -> None: ...
    def stop_drives(self) -> None: ...
    def status(self) -> dict[str, Any]: ...
