"""The CANopen master of the stand: boot, configure, supervise, and run a SYNC loop.

:meth:`Master.setup` resets the drives (NMT reset node, waits for each boot-up), sets
heartbeat, SYNC counter and cycle period, maps the PDOs over SDO, starts the nodes and
brings each drive to OPERATION ENABLED. :meth:`Master.run` then sends, every period, the
RPDOs (controlword + target) and a SYNC, and collects the TPDOs in a
:class:`~bus.sampler.Sampler`; it supervises heartbeats and EMCY all along and quick-stops
every drive at once when one fails.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
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
from bus.sampler import MissingPdos, Sampler, Samples
from bus.sync import (
    SYNC_COUNTER_OVERFLOW,
    SYNC_WINDOW_FRACTION,
    KernelSync,
    RealtimeClock,
    SyncCounter,
    SyncWatch,
    check_time_mode,
)
from bus.trace import MasterNetwork, Trace
from stand.errors import BusError, BusTimeout, InputError, RunAborted, StandError, StorageError

log = logging.getLogger(__name__)

#: Heartbeat period the drives are told to produce (0x1017), s.
HEARTBEAT_PERIOD_S = 0.1
#: Time a drive may take to send its boot-up message after NMT reset node, s.
BOOT_TIMEOUT_S = 2.0
#: Lockstep: time the TPDOs of one SYNC may take before they count as lost, s. Generous:
#: lockstep cannot tell a late TPDO from the next one, so a window must never close early
#: (a one-CPU User-Mode Linux guest on a loaded host stalls a reader for over 0.5 s).
PDO_TIMEOUT_S = 2.0
#: Longest single wait, so heartbeats and stop requests are checked while waiting, s.
POLL_S = 0.01
#: Stand time the drives spend in quick stop after a run before they are disabled, s.
STOP_RAMP_S = 0.1
#: A run aborts when a drive's TPDOs are missing for this many SYNCs in a row (lockstep:
#: each window waited ``pdo_timeout_s``; real time: at least ``pdo_timeout_s`` of SYNCs).
MISSING_PDO_SYNCS = 3
SYNC_PRODUCERS = ("auto", "kernel", "python")
#: Longest wait for the bus to hand back the last SYNC of the stop cycles, s.
ECHO_TIMEOUT_S = 0.5
#: Interfaces that hand the sender its own frames back with their bus stamp when asked
#: (``receive_own_messages``); the master takes each SYNC's time on the bus from the echo.
ECHO_INTERFACES = ("socketcan", "virtual")

ChunkCallback = Callable[[Samples, int, int], None]
ProgressCallback = Callable[[int, int], None]


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
        self._sync_counter = SyncCounter(SYNC_COUNTER_OVERFLOW)
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
              added_inertia_kgm2: float | None = None, time_mode: str = "lockstep") -> None:
        """Reset, configure and enable ``drives`` for SYNC period ``period_s`` seconds.

        In ``realtime`` the synchronous window 0x1007 is set to ``SYNC_WINDOW_FRACTION`` of
        the period (0, none, in ``lockstep``, where the master waits for every answer).

        ``added_inertia_kgm2`` is written to the simulated drive's 0x2100 (the first drive);
        a real drive has no such object and the operator attaches the disk by hand. Every
        device is checked (:meth:`~bus.drive.Drive.check_device`) before anything is written.
        """
        if period_s <= 0:
            raise InputError(f"period_s must be > 0, got {period_s}")
        self.time_mode = check_time_mode(time_mode)
        window_us = self._window_us(time_mode, period_s)
        ids = [d.node_id for d in drives]
        if len(set(ids)) != len(ids):
            raise InputError(f"node ids must differ, got {ids}")
        self._forget_drives()
        self.period_s = period_s
        self._quick_stop.clear()
        self._sync_counter = SyncCounter(SYNC_COUNTER_OVERFLOW)
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
        for n, drive in enumerate(self.drives):
            drive.write(PRODUCER_HEARTBEAT_TIME, 0, max(1, int(round(self.heartbeat_period_s * 1000))))
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

    def _check_nodes(self) -> BusError | None:
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
        self._sync_cycles(max(1, int(round(STOP_RAMP_S / self.period_s))) if self.period_s else 0)

    def _sync_cycles(self, cycles: int) -> None:
        """``cycles`` SYNCs, each after the drives' RPDOs; where the bus hands the SYNCs back,
        return once the last came back (so a trace being written holds it)."""
        counter = self._sync_counter
        last = threading.Event()
        data = b""

        def on_sync(can_id: int, echoed: bytearray, timestamp: float) -> None:
            if bytes(echoed) == data:
                last.set()

        if self.sync_echo:
            self.network.subscribe(SYNC_COB_ID, on_sync)
        try:
            for k in range(cycles):
                for d in self.drives:
                    if d.rpdo is not None:
                        self.network.send_message(d.rpdo_cob_id, d.rpdo_data(d.controlword, 0.0))
                value, frame = counter.next()
                if k == cycles - 1:
                    data = frame
                self.network.send_message(SYNC_COB_ID, frame)
                time.sleep(0 if self.time_mode == "lockstep" else self.period_s)
            if self.sync_echo and cycles:
                last.wait(ECHO_TIMEOUT_S)
        finally:
            if self.sync_echo:
                self.network.unsubscribe(SYNC_COB_ID, on_sync)

    # -- the run ---------------------------------------------------------------------------
    def run(self, targets: np.ndarray, *, time_mode: str = "lockstep",
            on_chunk: ChunkCallback | None = None, chunk_samples: int = 1000,
            stop: threading.Event | None = None, progress: ProgressCallback | None = None,
            trace_path: str | Path | None = None) -> Samples:
        """Send ``targets`` (drives × samples, SI units) one column per SYNC; record the TPDOs.

        The sample of window k is measured at SYNC k, before target k acts (as in
        :func:`stand.physics.simulate.simulate_motor`). The run is supervised: a heartbeat
        loss, an EMCY, a drive leaving OPERATIONAL, TPDOs of a drive missing for
        :data:`MISSING_PDO_SYNCS` SYNCs in a row, or a SYNC another producer sent quick-stops
        every drive and ends the run early; so do ``stop`` and Ctrl-C. Either way the samples
        so far are returned, with ``Samples.aborted`` saying why (and ``Samples.error`` the
        error), and the trace ends with the quick-stop frames.
        """
        check_time_mode(time_mode)
        targets = np.atleast_2d(np.asarray(targets, dtype=float))
        if targets.shape[0] != len(self.drives):
            raise InputError(f"targets: {len(self.drives)} drive(s) set up, got {targets.shape[0]} rows")
        if not self.drives or any(d.rpdo is None for d in self.drives):
            raise InputError("call setup() before run()")
        self._set_sync_window(time_mode)  # in case setup() was told another time mode
        n = targets.shape[1]
        tpdos = {cob: (dn, p, layout) for dn, d in enumerate(self.drives)
                 for p, (cob, layout) in enumerate(d.tpdos)}
        window_s = SYNC_WINDOW_FRACTION * self.period_s if time_mode == "realtime" else 0.0
        sampler = Sampler(tpdos, [d.id for d in self.drives], [d.config.scaling for d in self.drives],
                          n, self.period_s, window_s)
        trace = Trace(trace_path, (SYNC_COB_ID,) if self.sync_echo else ()) if trace_path else None
        if trace is not None:
            assert self.network.notifier is not None
            self.network.notifier.add_listener(trace)
            self.network.trace = trace
        for cob in tpdos:
            self.network.subscribe(cob, sampler.on_tpdo)
        echo = self.sync_echo and time_mode == "realtime"

        def on_sync_echo(can_id: int, data: bytearray, timestamp: float) -> None:
            sampler.sent(timestamp, data[0] if data else 0)

        if echo:
            self.network.subscribe(SYNC_COB_ID, on_sync_echo)
        counter = self._sync_counter
        kernel_period_s = self.period_s if self.kernel_sync and time_mode == "realtime" else None
        watch = self._sync_watch = SyncWatch(self.sync_echo, counter.upcoming(), counter.overflow,
                                             kernel_period_s)
        self.network.subscribe(SYNC_COB_ID, watch.on_sync)
        self.supervisor.expect_operational([d.id for d in self.drives])
        frames = [[(d.rpdo_cob_id, d.rpdo.pack([cia402.CW_ENABLE_OPERATION, raw]))
                   for raw in _raw_targets(d, targets[dn])] for dn, d in enumerate(self.drives)
                  if d.rpdo is not None]
        self._run_thread, self._stop_done = threading.get_ident(), threading.Event()
        self.time_mode, self.running, self.quick_stop_wall_s = time_mode, True, None
        realtime = time_mode == "realtime"
        kernel = (KernelSync(self.network.bus, self.period_s, counter)
                  if realtime and self.kernel_sync and self.network.bus is not None else None)
        clock = RealtimeClock(self.period_s, window_s) if realtime and kernel is None else None
        if kernel is not None:
            self.network.subscribe(SYNC_COB_ID, kernel.on_sync)
        missing = MissingPdos([d.id for d in self.drives], MISSING_PDO_SYNCS if not realtime else
                              max(MISSING_PDO_SYNCS, math.ceil(self.pdo_timeout_s / self.period_s)))
        send = self.network.send_message
        targets_sent = np.full(n, np.nan)  # time.time() once each window's RPDOs were sent
        error: StandError | None = None
        done = 0
        try:
            try:
                for k in range(n):
                    self.window = k
                    error = self._check_nodes()
                    if error is None and trace is not None and trace.error is not None:
                        error = StorageError(f"{trace.error}; every drive was quick-stopped")
                    if error is not None or self._quick_stop.is_set() or (stop is not None and stop.is_set()):
                        break
                    if kernel is not None:
                        wall = kernel.before_window(k, sampler.complete, window_s, self.pdo_timeout_s)
                        if wall is None:
                            error = BusTimeout(f"SYNC {k - 1} of the kernel's broadcast manager not "
                                               f"heard within {self.pdo_timeout_s} s; every drive was "
                                               "quick-stopped")
                            break
                    else:
                        wall = clock.wait() if clock is not None else time.monotonic()
                    if realtime and k > 0:  # a period after SYNC k-1: its answers are in
                        error = missing.check(k - 1, sampler.missing(k - 1))
                        if error is not None:
                            break
                    for per_drive in frames:
                        send(*per_drive[k])
                    targets_sent[k] = time.time()
                    value, data = counter.next()
                    sampler.open(k, wall, value)
                    watch.sent()
                    if kernel is None:
                        send(SYNC_COB_ID, data)
                        if not echo:
                            sampler.sent(time.time())
                    elif k == 0:
                        kernel.start()  # from now on the kernel sends a SYNC every period
                    done = k + 1
                    if not realtime:
                        error = self._await_window(sampler, stop)
                        if error is None:
                            error = missing.check(k, [] if sampler.complete.is_set()
                                                  else sampler.missing(k))
                        if error is not None:
                            break
                    if on_chunk is not None and done % chunk_samples == 0:
                        on_chunk(sampler.result(done), done - chunk_samples, done)
                    if progress is not None:
                        progress(done, n)
                if realtime and error is None:  # the TPDOs of the last window
                    if kernel is not None:
                        kernel.wait(done, self.pdo_timeout_s)
                    sampler.complete.wait(self.pdo_timeout_s)
            except KeyboardInterrupt:
                error = RunAborted("interrupted (Ctrl-C): drives quick-stopped")
            finally:
                if kernel is not None:
                    kernel.stop()
                    self.network.unsubscribe(SYNC_COB_ID, kernel.on_sync)
                sampler.close()
                self.running = False
                self.supervisor.release()
                self._sync_watch = None
                for cob in tpdos:
                    self.network.unsubscribe(cob, sampler.on_tpdo)
                self.network.unsubscribe(SYNC_COB_ID, watch.on_sync)
                if echo:
                    self.network.unsubscribe(SYNC_COB_ID, on_sync_echo)
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
            if trace is not None:
                self.network.trace = None
                assert self.network.notifier is not None
                self.network.notifier.remove_listener(trace)
                trace.stop()
        samples = sampler.result(done, aborted)
        samples.meta["error"] = error
        samples.meta["foreign_syncs"] = watch.foreign
        if kernel is not None:
            # The kernel's SYNC does not wait for the master: RPDOs sent after their SYNC
            # act one SYNC late, and the run is not the commanded one from there on.
            with np.errstate(invalid="ignore"):
                late = np.flatnonzero(targets_sent[:done] > samples.sync_stamp_s)
            samples.late_targets = int(late.size)
        self.late_target_windows = late.tolist() if kernel is not None else []
        samples.meta["trace_frames"] = trace.frames if trace is not None else 0
        if trace is not None and trace.error is not None:  # also a failure flushing at the end
            samples.meta["trace_error"] = str(trace.error)
        for d, ds in zip(self.drives, samples.drives, strict=True):
            self._counters[d.id] = {"lost": ds.lost, "duplicates": ds.duplicates, "late": ds.late}
        if on_chunk is not None and done % chunk_samples:
            on_chunk(samples, done - done % chunk_samples, done)
        return samples

    def _await_window(self, sampler: Sampler, stop: threading.Event | None) -> BusError | None:
        """Wait for the open window's TPDOs, supervising; return an error or None (all came,
        a stop was asked, or the PDO timeout passed: the caller counts what is missing)."""
        deadline = time.monotonic() + self.pdo_timeout_s
        while not sampler.complete.wait(min(POLL_S, max(0.0, deadline - time.monotonic()))):
            error = self._check_nodes()
            if error is not None:
                return error
            if time.monotonic() >= deadline or self._quick_stop.is_set() or (
                    stop is not None and stop.is_set()):
                return None
        return None

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
        self._forget_drives()
        self.network.disconnect()

    def __enter__(self) -> Master:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _raw_targets(drive: Drive, values: np.ndarray) -> list[int]:
    scaling, mode = drive.config.scaling, drive.config.mode
    return [scaling.target_raw(mode, float(v)) for v in values]
