"""The CANopen master of the stand: boot, configure, supervise, and run a SYNC loop.

:meth:`Master.setup` resets the drives (NMT reset node, waits for each boot-up), sets
heartbeat, SYNC counter and cycle period, maps the PDOs over SDO, starts the nodes and
brings each drive to OPERATION ENABLED. :meth:`Master.run` then sends, every period, the
RPDOs (controlword + target) and a SYNC, and collects the TPDOs in a
:class:`~bus.sampler.Sampler` (the windows are :class:`~bus.run_loop.RunLoop`'s); it
supervises heartbeats and EMCY all along and quick-stops every drive at once when one fails.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bus import cia402
from bus.adapters import BusConfig, connect_network, has_kernel_timers
from bus.cia301 import (
    COMMUNICATION_CYCLE_PERIOD,
    NMT_COB_ID,
    NMT_ENTER_PRE_OPERATIONAL,
    NMT_RESET_NODE,
    NMT_START,
    PRODUCER_HEARTBEAT_TIME,
    SYNC_COB_ID,
    SYNCHRONOUS_COUNTER_OVERFLOW,
    SYNCHRONOUS_WINDOW_LENGTH,
)
from bus.drive import SDO_TIMEOUT_S, Drive, DriveConfig
from bus.heartbeat import HEARTBEAT_CONSUMER_FACTOR, Supervisor
from bus.run_loop import ChunkCallback, ProgressCallback, RunLoop, sync_cycles
from bus.sampler import Samples
from bus.sync import (
    SYNC_COUNTER_OVERFLOW,
    SYNC_WINDOW_FRACTION,
    SyncCounter,
    SyncWatch,
    check_time_mode,
)
from bus.trace import MasterNetwork, Trace
from stand.errors import BusError, BusTimeout, InputError, StandError

log = logging.getLogger(__name__)

#: Heartbeat period the drives are told to produce (0x1017), s.
HEARTBEAT_PERIOD_S = 0.1
#: Time a drive may take to send its boot-up message after NMT reset node, s.
BOOT_TIMEOUT_S = 2.0
#: Lockstep: time the TPDOs of one SYNC may take before they count as lost, s. Generous:
#: lockstep cannot tell a late TPDO from the next one, so a window must never close early
#: (a one-CPU User-Mode Linux guest on a loaded host stalls a reader for over 0.5 s).
PDO_TIMEOUT_S = 2.0
#: Stand time the drives spend in quick stop after a run before they are disabled, s.
STOP_RAMP_S = 0.1
SYNC_PRODUCERS = ("auto", "kernel", "python")
#: Interfaces that hand the sender its own frames back with their bus stamp when asked
#: (``receive_own_messages``); the master takes each SYNC's time on the bus from the echo.
ECHO_INTERFACES = ("socketcan", "virtual")


class Master:
    """The stand's CANopen master on one bus.

    Parameters
    ----------
    config : BusConfig
        The bus.
    heartbeat_period_s, sdo_timeout_s, pdo_timeout_s, boot_timeout_s : float
        Timeouts (the module constants by default; tests shrink them), s.
    heartbeat_consumer_factor : float
        Heartbeat consumer time as a multiple of the producer period (> 1, CiA 301).
    sync_producer : {'auto', 'kernel', 'python'}
        Who sends the real-time SYNCs: the kernel's broadcast manager (``kernel``; SocketCAN
        only), the master's Python clock (``python``), or the kernel where the bus has one
        (``auto``).
    """

    def __init__(self, config: BusConfig | None = None, *,
                 heartbeat_period_s: float = HEARTBEAT_PERIOD_S,
                 sdo_timeout_s: float = SDO_TIMEOUT_S, pdo_timeout_s: float = PDO_TIMEOUT_S,
                 boot_timeout_s: float = BOOT_TIMEOUT_S,
                 heartbeat_consumer_factor: float = HEARTBEAT_CONSUMER_FACTOR,
                 sync_producer: str = "auto") -> None:
        if sync_producer not in SYNC_PRODUCERS:
            raise InputError(f"sync_producer must be one of {', '.join(SYNC_PRODUCERS)}, "
                             f"not {sync_producer!r}")
        self.config = config or BusConfig()
        #: Real time: each window's SYNC is stamped from its echo (its own bus stamp, in bus
        #: order with the answers); elsewhere from the time ``send`` returned.
        self.sync_echo = self.config.interface in ECHO_INTERFACES
        bus_config = self.config
        if self.sync_echo:
            # The master's receive filters pass 0x080, so of its own frames only SYNC returns.
            bus_config = bus_config.with_default("receive_own_messages", True)
        self.heartbeat_period_s = heartbeat_period_s
        self.sdo_timeout_s = sdo_timeout_s
        self.pdo_timeout_s = pdo_timeout_s
        self.boot_timeout_s = boot_timeout_s
        self.network = MasterNetwork()
        self.network.channel = self.config.channel
        connect_network(bus_config, self.network, role="master")
        kernel_timers = has_kernel_timers(self.network.bus)
        if sync_producer == "kernel" and not kernel_timers:
            self.network.disconnect()
            raise InputError(f"sync_producer 'kernel' needs SocketCAN's broadcast manager; interface "
                             f"{self.config.interface!r} has none: use 'python' or 'auto'")
        #: Real-time SYNCs come from the kernel's broadcast manager.
        self.kernel_sync = kernel_timers and sync_producer != "python"
        self.drives: list[Drive] = []
        self.supervisor = Supervisor(self.network, heartbeat_consumer_factor)
        self._counters: dict[int, dict[str, int]] = {}
        self._quick_stop = threading.Event()
        #: One counter for every SYNC the master sends (0x1019 is set on the drives).
        self.sync_counter = SyncCounter(SYNC_COUNTER_OVERFLOW)
        self._window_written_us = 0
        self._sync_watch: SyncWatch | None = None
        #: The thread of the run going on, and set once its stop SYNCs went out.
        self._run_thread: int | None = None
        self._stop_done = threading.Event()
        self.running = False
        self.period_s = 0.0
        self.window = 0
        self.time_mode = "lockstep"
        self.quick_stop_wall_s: float | None = None
        #: Windows of the last run whose targets left after their (kernel's) SYNC.
        self.late_target_windows: list[int] = []

    # -- setup -----------------------------------------------------------------------------
    def _forget_drives(self) -> None:
        for drive in self.drives:
            self.supervisor.forget(drive.id)
            self.network.nodes.pop(drive.id, None)
        self.drives = []

    def setup(self, drives: Sequence[DriveConfig], period_s: float,
              added_inertia_kgm2: float | None = None, time_mode: str = "lockstep",
              trace_path: str | Path | None = None) -> None:
        """Reset, configure and enable ``drives`` for SYNC period ``period_s`` seconds.

        In ``realtime`` the synchronous window 0x1007 is set to ``SYNC_WINDOW_FRACTION`` of
        the period (0, none, in ``lockstep``, where the master waits for every answer).

        ``added_inertia_kgm2`` is written to the simulated drive's 0x2100 (the first drive);
        a real drive has no such object and the operator attaches the disk by hand. Every
        device is checked (:meth:`~bus.drive.Drive.check_device`, then its units,
        :meth:`~bus.drive.Drive.check_units`) before anything is written.

        With ``trace_path`` the trace starts before the NMT reset and goes on through the
        next :meth:`run`: it holds the SDO traffic that says what the run's frames mean (the
        PDO mappings, the cycle period 0x1006, the drives' units 0x6075 and 0x608F), so
        :func:`bus.tracereader.decode_trace` needs nothing else.
        """
        if period_s <= 0:
            raise InputError(f"period_s must be > 0, got {period_s}")
        self.time_mode = check_time_mode(time_mode)
        window_us = self._window_us(time_mode, period_s)
        ids = [d.node_id for d in drives]
        if len(set(ids)) != len(ids):
            raise InputError(f"node ids must differ, got {ids}")
        self.network.end_trace()
        if trace_path is not None:
            self._start_trace(trace_path)
        try:
            self._configure(drives, period_s, added_inertia_kgm2, window_us)
        except BaseException:
            self.network.end_trace()
            raise

    def _start_trace(self, path: str | Path) -> Trace:
        """Write every frame to the trace ``path`` from now on; where the bus hands the
        master's SYNCs back, the echoes are the trace's SYNC frames (with their bus stamp)."""
        return self.network.start_trace(path, (SYNC_COB_ID,) if self.sync_echo else ())

    def _configure(self, drives: Sequence[DriveConfig], period_s: float,
                   added_inertia_kgm2: float | None, window_us: int) -> None:
        """:meth:`setup` from the NMT reset to OPERATION ENABLED."""
        self._forget_drives()
        self.period_s = period_s
        self._quick_stop.clear()
        self.sync_counter = SyncCounter(SYNC_COUNTER_OVERFLOW)
        self.drives = [Drive(self.network, d, self.sdo_timeout_s) for d in drives]
        for drive in self.drives:
            self.supervisor.watch(drive.id)
            self._counters[drive.id] = {"lost": 0, "duplicates": 0, "late": 0}
        for drive in self.drives:
            self.network.send_message(NMT_COB_ID, bytes([NMT_RESET_NODE, drive.id]))
        for drive in self.drives:
            if not self.supervisor.booted[drive.id].wait(self.boot_timeout_s):
                raise BusTimeout(f"node {drive.id}: no boot-up message within {self.boot_timeout_s} s "
                                 "after NMT reset node; is the drive powered, on this bus, at this id?")
        for drive in self.drives:  # every device checked before anything is written to any
            drive.check_device()
            drive.check_units()
        for n, drive in enumerate(self.drives):
            drive.write(PRODUCER_HEARTBEAT_TIME, 0, max(1, int(round(self.heartbeat_period_s * 1000))))
            self.supervisor.producing(drive.id)
            if drive.has(SYNCHRONOUS_COUNTER_OVERFLOW):
                drive.write(SYNCHRONOUS_COUNTER_OVERFLOW, 0, SYNC_COUNTER_OVERFLOW)
            if drive.has(COMMUNICATION_CYCLE_PERIOD):
                drive.write(COMMUNICATION_CYCLE_PERIOD, 0, int(round(period_s * 1e6)))
            if drive.has(SYNCHRONOUS_WINDOW_LENGTH):
                drive.write(SYNCHRONOUS_WINDOW_LENGTH, 0, window_us)
            if n == 0 and added_inertia_kgm2 is not None:
                if drive.simulated and drive.has(cia402.ADDED_INERTIA):
                    drive.write(cia402.ADDED_INERTIA, 0, float(added_inertia_kgm2))
                elif added_inertia_kgm2:
                    log.warning("node %d: attach the %.4g kg·m² disk now (real drive)",
                                drive.id, added_inertia_kgm2)
            drive.write(cia402.MODES_OF_OPERATION, 0, cia402.MODES[drive.config.mode])
            drive.configure_pdos()
        self._window_written_us = window_us
        for drive in self.drives:
            self.network.send_message(NMT_COB_ID, bytes([NMT_START, drive.id]))
        for drive in self.drives:
            drive.enable()

    @staticmethod
    def _window_us(time_mode: str, period_s: float) -> int:
        return int(SYNC_WINDOW_FRACTION * period_s * 1e6) if time_mode == "realtime" else 0

    def _set_sync_window(self, time_mode: str) -> None:
        """Write the synchronous window 0x1007 of ``time_mode`` to every drive that has it."""
        window_us = self._window_us(time_mode, self.period_s)
        if window_us != self._window_written_us:
            for drive in self.drives:
                if drive.has(SYNCHRONOUS_WINDOW_LENGTH):
                    drive.write(SYNCHRONOUS_WINDOW_LENGTH, 0, window_us)
            self._window_written_us = window_us

    # -- supervision -----------------------------------------------------------------------
    def heartbeat_age_s(self, node_id: int) -> float | None:
        return self.supervisor.age_s(node_id)

    def check_nodes(self) -> BusError | None:
        """Heartbeats, EMCY, NMT states and (during a run) foreign SYNCs of the drives."""
        error = self.supervisor.check([d.id for d in self.drives], self.heartbeat_period_s)
        watch = self._sync_watch
        return error if error is not None or watch is None else watch.error()

    def quick_stop_all(self) -> None:
        """Send CiA 402 quick stop to every drive at once (RPDO frames, back to back).

        Safe to call from any thread; a running :meth:`run` ends after its current SYNC. A
        synchronous RPDO acts at the next SYNC, so SYNCs follow (:meth:`_stop_cycles`); from
        another thread than the run's it returns once they went out.
        """
        self._quick_stop.set()
        stopped = self._stop_done
        wait = self.running and threading.get_ident() != self._run_thread
        frames = [(d.rpdo_cob_id, d.rpdo_data(cia402.CW_QUICK_STOP, 0.0))
                  for d in self.drives if d.rpdo is not None]
        if self.quick_stop_wall_s is None:
            self.quick_stop_wall_s = time.monotonic()  # when the first quick stop left
        for cob_id, data in frames:
            self.network.send_message(cob_id, data)
        for drive in self.drives:
            drive.controlword = cia402.CW_QUICK_STOP
        if not self.running:
            self._stop_cycles()
        elif wait:  # from another thread (POST /stop): return once the run's stop SYNCs went
            stopped.wait(self.pdo_timeout_s + STOP_RAMP_S)

    def _stop_cycles(self) -> None:
        """SYNCs with quick-stop RPDOs for ``STOP_RAMP_S``: a synchronous RPDO acts at the
        next SYNC (and the drives brake meanwhile)."""
        sync_cycles(self, max(1, int(round(STOP_RAMP_S / self.period_s))) if self.period_s else 0)

    # -- the run ---------------------------------------------------------------------------
    @property
    def quick_stop_requested(self) -> bool:
        """A quick stop was asked (:meth:`quick_stop_all`) since the drives were set up."""
        return self._quick_stop.is_set()

    def run(self, targets: np.ndarray, *, time_mode: str = "lockstep",
            on_chunk: ChunkCallback | None = None, chunk_samples: int = 1000,
            stop: threading.Event | None = None, progress: ProgressCallback | None = None,
            trace_path: str | Path | None = None) -> Samples:
        """Send ``targets`` (drives × samples, SI units) one column per SYNC; record the TPDOs.

        The sample of window k is measured at SYNC k, before target k acts (as in
        :func:`stand.physics.simulate.simulate_motor`). The run is supervised: a heartbeat
        loss, an EMCY, a drive leaving OPERATIONAL, TPDOs of a drive missing for
        :data:`~bus.run_loop.MISSING_PDO_SYNCS` SYNCs in a row, or a SYNC another producer
        sent quick-stops every drive and ends the run early; so do ``stop`` and Ctrl-C.
        Either way the samples so far are returned, with ``Samples.aborted`` saying why (and
        ``Samples.error`` the error), and the trace ends with the quick-stop frames. The
        windows themselves are :class:`~bus.run_loop.RunLoop`'s.
        """
        check_time_mode(time_mode)
        targets = np.atleast_2d(np.asarray(targets, dtype=float))
        if targets.shape[0] != len(self.drives):
            raise InputError(f"targets: {len(self.drives)} drive(s) set up, got {targets.shape[0]} rows")
        if not self.drives or any(d.rpdo is None for d in self.drives):
            raise InputError("call setup() before run()")
        tracing = self.network.trace
        if trace_path is not None and tracing is not None and Path(trace_path) != tracing.path:
            raise InputError(f"trace_path {trace_path}: setup() started the trace {tracing.path}; "
                             "give run() the same file or none")
        self._set_sync_window(time_mode)  # in case setup() was told another time mode
        loop = RunLoop(self, targets, time_mode)
        trace = tracing
        if trace is None and trace_path is not None:
            trace = self._start_trace(trace_path)
        self._sync_watch = loop.watch
        self.supervisor.expect_operational([d.id for d in self.drives])
        self._run_thread, self._stop_done = threading.get_ident(), threading.Event()
        self.time_mode, self.running, self.quick_stop_wall_s = time_mode, True, None
        error: StandError | None = None
        try:
            try:
                error = loop.cycle(on_chunk, chunk_samples, stop, progress, trace)
            finally:
                self.running = False
                self.supervisor.release()
                self._sync_watch = None
            # The quick stop goes into the trace: it ends with the stop frames.
            aborted: str | None = None
            if error is not None:
                self.quick_stop_all()
                aborted = str(error)
            elif self._quick_stop.is_set():  # asked from another thread while the run went on
                self._stop_cycles()
                aborted = "quick stop requested"
            elif stop is not None and stop.is_set():
                self.quick_stop_all()
                aborted = "stop requested"
        finally:
            self._stop_done.set()
            self.network.end_trace()
        samples = loop.samples(aborted, error, trace)
        self.late_target_windows = loop.late_target_windows
        for d, ds in zip(self.drives, samples.drives, strict=True):
            self._counters[d.id] = {"lost": ds.lost, "duplicates": ds.duplicates, "late": ds.late}
        if on_chunk is not None and loop.done % chunk_samples:
            on_chunk(samples, loop.done - loop.done % chunk_samples, loop.done)
        return samples

    def stop_drives(self) -> None:
        """End of a run: quick stop, let the drives brake, disable them, NMT pre-operational."""
        if not self.drives:
            return
        if self.quick_stop_wall_s is None:
            self.quick_stop_all()
        for drive in self.drives:
            try:
                drive.disable()
            except BusError as exc:
                log.warning("%s", exc)
            self.network.send_message(NMT_COB_ID, bytes([NMT_ENTER_PRE_OPERATIONAL, drive.id]))

    def status(self) -> dict[str, Any]:
        """Nodes, NMT states, heartbeat ages, EMCY and PDO error counters (JSON data)."""
        nodes = []
        for drive in self.drives:
            nodes.append({"node_id": drive.id, "mode": drive.config.mode,
                          **self.supervisor.node_status(drive.id),
                          **self._counters.get(drive.id, {})})
        return {"interface": self.config.interface, "channel": self.config.channel,
                "running": self.running, "time_mode": self.time_mode, "period_s": self.period_s,
                "window": self.window, "nodes": nodes}

    def close(self) -> None:
        """Stop the reader thread and shut the bus down (drives are left as they are)."""
        self.network.end_trace()
        self._forget_drives()
        self.network.disconnect()

    def __enter__(self) -> Master:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

