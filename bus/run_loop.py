"""The run loop: one SYNC window per column of targets, the drives' TPDOs collected.

:meth:`bus.master.Master.run` sets the drives' state around it; :class:`RunLoop` does what
happens in between. Every period it sends each drive's RPDO (controlword + target) and a
SYNC, or, with the kernel's broadcast manager sending the SYNCs, follows them; each SYNC
opens a window of a :class:`~bus.sampler.Sampler` that the TPDOs answering it fill. Between
windows it supervises the drives (:meth:`~bus.master.Master.check_nodes`) and counts the
SYNCs in a row a drive's TPDOs were missing. It ends at the last window, on the first error,
or when a stop is asked; what to do then (quick stop) is the master's.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from bus import cia402
from bus.drive import Drive
from bus.sampler import MissingPdos, Sampler, Samples
from bus.sync import SYNC_COB_ID, SYNC_WINDOW_FRACTION, KernelSync, RealtimeClock, SyncWatch
from bus.trace import Trace
from stand.errors import BusError, BusTimeout, RunAborted, StandError, StorageError

if TYPE_CHECKING:
    from bus.master import Master

#: Longest single wait, so heartbeats and stop requests are checked while waiting, s.
POLL_S = 0.01
#: Longest wait for the bus to hand back the last SYNC of :func:`sync_cycles`, s.
ECHO_TIMEOUT_S = 0.5
#: A run aborts when a drive's TPDOs are missing for this many SYNCs in a row (lockstep:
#: each window waited ``pdo_timeout_s``; real time: at least ``pdo_timeout_s`` of SYNCs).
MISSING_PDO_SYNCS = 3

ChunkCallback = Callable[[Samples, int, int], None]
ProgressCallback = Callable[[int, int], None]


class RunLoop:
    """One run of ``targets`` (drives × samples, SI units) on ``master``'s drives.

    Parameters
    ----------
    master : Master
        The master whose drives are set up (RPDO and TPDOs mapped).
    targets : ndarray
        One row per drive, one column per SYNC, in the drive mode's SI unit.
    time_mode : {'lockstep', 'realtime'}
        Lockstep: each window waits for its TPDOs. Real time: one SYNC a period, from the
        kernel's broadcast manager where the master has it, else from a Python clock.
    """

    def __init__(self, master: Master, targets: np.ndarray, time_mode: str) -> None:
        self.master = master
        self.realtime = time_mode == "realtime"
        self.n = targets.shape[1]
        drives = master.drives
        self.tpdos = {cob: (dn, p, layout) for dn, d in enumerate(drives)
                      for p, (cob, layout) in enumerate(d.tpdos)}
        self.window_s = SYNC_WINDOW_FRACTION * master.period_s if self.realtime else 0.0
        self.sampler = Sampler(self.tpdos, [d.id for d in drives], [d.config.scaling for d in drives],
                               self.n, master.period_s, self.window_s,
                               [cia402.TARGET_OBJECT[d.config.mode][0] for d in drives],
                               [d.config.current_mean for d in drives],
                               [d.simulated for d in drives])
        self.echo = master.sync_echo and self.realtime
        counter = master.sync_counter
        kernel_period_s = master.period_s if master.kernel_sync and self.realtime else None
        self.watch = SyncWatch(master.sync_echo, counter.upcoming(), counter.overflow, kernel_period_s)
        #: Each drive's raw targets, and the RPDO frame of each window.
        self.raw_targets = [_raw_targets(d, targets[dn]) for dn, d in enumerate(drives)]
        self.frames = [[(d.rpdo_cob_id, d.rpdo.pack([cia402.CW_ENABLE_OPERATION, raw]))
                        for raw in self.raw_targets[dn]] for dn, d in enumerate(drives)
                       if d.rpdo is not None]
        bus = master.network.bus
        self.kernel = (KernelSync(bus, master.period_s, counter)
                       if self.realtime and master.kernel_sync and bus is not None else None)
        self.clock = (RealtimeClock(master.period_s, self.window_s)
                      if self.realtime and self.kernel is None else None)
        ids = [d.id for d in drives]
        self.missing = MissingPdos(ids, MISSING_PDO_SYNCS if not self.realtime else
                                   max(MISSING_PDO_SYNCS, math.ceil(master.pdo_timeout_s / master.period_s)))
        #: ``time.time()`` once each window's RPDOs were sent.
        self.targets_sent = np.full(self.n, np.nan)
        #: Windows whose SYNC went out.
        self.done = 0
        #: Windows whose targets left after their (kernel's) SYNC.
        self.late_target_windows: list[int] = []

    def _on_sync_echo(self, can_id: int, data: bytearray, timestamp: float) -> None:
        self.sampler.sent(timestamp, data[0] if data else 0)

    def _subscribe(self) -> None:
        network = self.master.network
        for cob in self.tpdos:
            network.subscribe(cob, self.sampler.on_tpdo)
        if self.echo:
            network.subscribe(SYNC_COB_ID, self._on_sync_echo)
        network.subscribe(SYNC_COB_ID, self.watch.on_sync)
        if self.kernel is not None:
            network.subscribe(SYNC_COB_ID, self.kernel.on_sync)

    def _unsubscribe(self) -> None:
        network = self.master.network
        if self.kernel is not None:
            self.kernel.stop()
            network.unsubscribe(SYNC_COB_ID, self.kernel.on_sync)
        self.sampler.close()
        for cob in self.tpdos:
            network.unsubscribe(cob, self.sampler.on_tpdo)
        network.unsubscribe(SYNC_COB_ID, self.watch.on_sync)
        if self.echo:
            network.unsubscribe(SYNC_COB_ID, self._on_sync_echo)

    def cycle(self, on_chunk: ChunkCallback | None, chunk_samples: int,
              stop: threading.Event | None, progress: ProgressCallback | None,
              trace: Trace | None) -> StandError | None:
        """Send the windows; return the error that ended the run early, or None.

        Ctrl-C ends it as :class:`~stand.errors.RunAborted`. The sampler is closed and every
        subscription taken back on the way out, whatever happens.
        """
        master, sampler, kernel = self.master, self.sampler, self.kernel
        send = master.network.send_message
        counter = master.sync_counter
        error: StandError | None = None
        self._subscribe()
        try:
            for k in range(self.n):
                master.window = k
                error = master.check_nodes()
                if error is None and trace is not None and trace.error is not None:
                    error = StorageError(f"{trace.error}; every drive was quick-stopped")
                if error is not None or master.quick_stop_requested or (stop is not None and stop.is_set()):
                    break
                if kernel is not None:
                    wall = kernel.before_window(k, sampler.complete, self.window_s, master.pdo_timeout_s)
                    if wall is None:
                        error = BusTimeout(f"SYNC {k - 1} of the kernel's broadcast manager not "
                                           f"heard within {master.pdo_timeout_s} s; every drive was "
                                           "quick-stopped")
                        break
                else:
                    wall = self.clock.wait() if self.clock is not None else time.monotonic()
                if self.realtime and k > 0:  # a period after SYNC k-1: its answers are in
                    error = self.missing.check(k - 1, sampler.missing(k - 1))
                    if error is not None:
                        break
                for dn, per_drive in enumerate(self.frames):
                    send(*per_drive[k])
                    sampler.command(dn, k, self.raw_targets[dn][k])
                self.targets_sent[k] = time.time()
                value, data = counter.next()
                sampler.open(k, wall, value)
                self.watch.sent()
                if kernel is None:
                    send(SYNC_COB_ID, data)
                    if not self.echo:
                        sampler.sent(time.time())
                elif k == 0:
                    kernel.start()  # from now on the kernel sends a SYNC every period
                self.done = done = k + 1
                if not self.realtime:
                    error = self._await_window(stop)
                    if error is None:
                        error = self.missing.check(k, [] if sampler.complete.is_set()
                                                   else sampler.missing(k))
                    if error is not None:
                        break
                if on_chunk is not None and done % chunk_samples == 0:
                    on_chunk(sampler.result(done), done - chunk_samples, done)
                if progress is not None:
                    progress(done, self.n)
            if self.realtime and error is None:  # the TPDOs of the last window
                if kernel is not None:
                    kernel.wait(self.done, master.pdo_timeout_s)
                sampler.complete.wait(master.pdo_timeout_s)
        except KeyboardInterrupt:
            error = RunAborted("interrupted (Ctrl-C): drives quick-stopped")
        finally:
            self._unsubscribe()
        return error

    def _await_window(self, stop: threading.Event | None) -> BusError | None:
        """Wait for the open window's TPDOs, supervising; return an error or None (all came,
        a stop was asked, or the PDO timeout passed: the caller counts what is missing)."""
        master, sampler = self.master, self.sampler
        deadline = time.monotonic() + master.pdo_timeout_s
        while not sampler.complete.wait(min(POLL_S, max(0.0, deadline - time.monotonic()))):
            error = master.check_nodes()
            if error is not None:
                return error
            if time.monotonic() >= deadline or master.quick_stop_requested or (
                    stop is not None and stop.is_set()):
                return None
        return None

    def samples(self, aborted: str | None, error: StandError | None, trace: Trace | None) -> Samples:
        """The run's samples, with why it ended early, the foreign SYNCs heard and the targets
        that left after their SYNC (kernel SYNC only)."""
        done = self.done
        samples = self.sampler.result(done, aborted)
        samples.meta["error"] = error
        samples.meta["foreign_syncs"] = self.watch.foreign
        if self.kernel is not None:
            # The kernel's SYNC does not wait for the master: RPDOs sent after their SYNC
            # act one SYNC late, and the run is not the commanded one from there on.
            with np.errstate(invalid="ignore"):
                late = np.flatnonzero(self.targets_sent[:done] > samples.sync_stamp_s)
            samples.late_targets = int(late.size)
            self.late_target_windows = late.tolist()
        samples.meta["trace_frames"] = trace.frames if trace is not None else 0
        if trace is not None and trace.error is not None:  # also a failure flushing at the end
            samples.meta["trace_error"] = str(trace.error)
        return samples


def sync_cycles(master: Master, cycles: int) -> None:
    """``cycles`` SYNCs outside a run, each after the drives' RPDOs with their present
    controlword and a zero target (a synchronous RPDO acts only at the next SYNC: the stop
    cycles after a quick stop). Where the bus hands the SYNCs back, it returns once the last
    came back (so a trace being written holds it).

    In lockstep each SYNC goes once every drive answered the one before, as in a run
    (:class:`_Answers`): sent back to back, the SYNCs queue up before the drives, and the
    SDO that follows them (the disable of a stop) waits behind all of them beyond its
    timeout (seen on a loaded User-Mode Linux guest on every run)."""
    network, counter = master.network, master.sync_counter
    last = threading.Event()
    data = b""

    def on_sync(can_id: int, echoed: bytearray, timestamp: float) -> None:
        if bytes(echoed) == data:
            last.set()

    if master.sync_echo:
        network.subscribe(SYNC_COB_ID, on_sync)
    answers = _Answers(master) if master.time_mode == "lockstep" else None
    try:
        for k in range(cycles):
            for d in master.drives:
                if d.rpdo is not None:
                    network.send_message(d.rpdo_cob_id, d.rpdo_data(d.controlword, 0.0))
            value, frame = counter.next()
            if k == cycles - 1:
                data = frame
            network.send_message(SYNC_COB_ID, frame)
            if answers is not None:
                answers.wait(k + 1)
            else:
                time.sleep(master.period_s)
        if master.sync_echo and cycles:
            last.wait(ECHO_TIMEOUT_S)
    finally:
        if master.sync_echo:
            network.unsubscribe(SYNC_COB_ID, on_sync)
        if answers is not None:
            answers.close()


class _Answers:
    """Counts each drive's answers to SYNCs outside a run: its last TPDO of each SYNC."""

    def __init__(self, master: Master) -> None:
        self.network = master.network
        self.timeout_s = master.pdo_timeout_s
        self.counts = {d.tpdos[-1][0]: 0 for d in master.drives if d.tpdos}
        self.changed = threading.Condition()
        #: False once a drive did not answer within the PDO timeout: the SYNCs left go
        #: without waiting (a drive that left OPERATIONAL never answers).
        self.waiting = True
        for cob_id in self.counts:
            self.network.subscribe(cob_id, self._on_tpdo)

    def _on_tpdo(self, can_id: int, data: bytearray, timestamp: float) -> None:
        with self.changed:
            self.counts[can_id] += 1
            self.changed.notify_all()

    def wait(self, answers: int) -> None:
        """Return once every drive answered ``answers`` SYNCs, or the PDO timeout passed."""
        if not self.waiting:
            return
        with self.changed:
            self.waiting = self.changed.wait_for(
                lambda: all(n >= answers for n in self.counts.values()), self.timeout_s)

    def close(self) -> None:
        for cob_id in self.counts:
            self.network.unsubscribe(cob_id, self._on_tpdo)


def _raw_targets(drive: Drive, values: np.ndarray) -> list[int]:
    scaling, mode = drive.config.scaling, drive.config.mode
    return [scaling.target_raw(mode, float(v)) for v in values]
