"""Raw traffic of a run, in a standard python-can log format chosen by suffix.

``.log`` (candump), ``.asc`` (Vector ASCII) or ``.blf`` (Vector binary). Frames the master
receives come from the bus reader thread, frames it sends from the sender, the master's
:class:`MasterNetwork`; both are queued and written by the trace's own thread.
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from pathlib import Path

import can
import canopen

from stand.errors import BusError, InputError, StorageError

TRACE_SUFFIXES = (".log", ".asc", ".blf")
#: Frames the trace's writer may fall behind before the trace ends (about 25 s of a 1 Mbit/s
#: bus at full load, some 100 MB of queued messages).
MAX_BEHIND_FRAMES = 200_000


class Trace(can.Listener):
    """A thread-safe writer of one trace file, on a thread of its own.

    Frames are queued by the threads that hear or send them and written by the trace's own
    thread. A file that takes writes slowly (a busy disk, a network share, a pipe) holds
    the trace back, never the bus reader: the reader hands on every TPDO, SDO answer,
    heartbeat and EMCY in time, and a window closed while it waited on the disk would lose
    its samples. A write that fails (a full disk, a file system gone) ends the trace, never
    the caller; the failure is kept in :attr:`error` for the run to act on, as is a writer
    that falls more than :data:`MAX_BEHIND_FRAMES` behind.
    """

    def __init__(self, path: str | Path, echoed: tuple[int, ...] = ()) -> None:
        #: 11-bit ids the master's bus hands back to it: logged as they come back (with
        #: their bus stamp, among whatever else is on the bus on that id: the kernel's
        #: SYNCs, another producer's), not when sent.
        self.echoed = frozenset(echoed)
        self.path = Path(path)
        if self.path.suffix not in TRACE_SUFFIXES:
            raise InputError(f"trace file must end in {', '.join(TRACE_SUFFIXES)}: {self.path}")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._writer = can.Logger(str(self.path))
        self._queue: queue.SimpleQueue[can.Message | None] = queue.SimpleQueue()
        self._lock = threading.Lock()
        #: Frames written so far.
        self.frames = 0
        self._closed = False
        #: Why the trace ended early, or None.
        self.error: StorageError | None = None
        self._thread = threading.Thread(target=self._write_queued, name=f"trace-{self.path.name}",
                                        daemon=True)
        self._thread.start()

    def on_message_received(self, msg: can.Message) -> None:
        self._put(msg)

    def sent(self, msg: can.Message) -> None:
        """Log a frame the master sent (stamped now), unless the bus hands it back."""
        if not msg.is_extended_id and msg.arbitration_id in self.echoed:
            return
        msg.timestamp = time.time()
        self._put(msg)

    def _put(self, msg: can.Message) -> None:
        with self._lock:  # one order for frames heard and sent, none after stop()
            if self._closed or self.error is not None:
                return
            if self._queue.qsize() > MAX_BEHIND_FRAMES:
                self.error = StorageError(
                    f"cannot write trace file {self.path} fast enough: {MAX_BEHIND_FRAMES} frames "
                    f"waiting; the trace ends after {self.frames} frames")
                return
            self._queue.put(msg)

    def _write_queued(self) -> None:
        """The writer thread: frames in the order queued until :meth:`stop`, then the file's
        end (its last buffered frames) is written."""
        while (msg := self._queue.get()) is not None:
            if self.error is not None:
                continue  # the file is lost: the queue is only drained
            try:
                self._writer.on_message_received(msg)
            except Exception as exc:  # any failure of the file ends the trace
                self._fail(exc)
                continue
            self.frames += 1
        try:
            self._writer.stop()
        except Exception as exc:  # reported as a failed write is
            if self.error is None:
                self._fail(exc)

    def _fail(self, exc: Exception) -> None:
        """End the trace after a failed write."""
        self.error = StorageError(f"cannot write trace file {self.path}: {exc}; the trace ends "
                                  f"after {self.frames} frames")
        with contextlib.suppress(Exception):  # the file is already lost; closing is best effort
            self._writer.stop()

    def stop(self) -> None:
        """Write what is queued and close the file (returns once it is written)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._queue.put(None)
        self._thread.join()


class MasterNetwork(canopen.Network):
    """A canopen network that also logs the frames it sends to the run's trace."""

    #: The trace being written: every frame the bus hands on, and every frame sent.
    trace: Trace | None = None
    channel: str | None = None

    def start_trace(self, path: str | Path, echoed: tuple[int, ...] = ()) -> Trace:
        """Write every frame to the trace ``path`` from now on (see :class:`Trace`)."""
        self.end_trace()
        trace = Trace(path, echoed)
        assert self.notifier is not None, "connect the network first"
        self.notifier.add_listener(trace)
        self.trace = trace
        return trace

    def end_trace(self) -> None:
        """Close the trace being written, if any (its last frames are flushed)."""
        trace, self.trace = self.trace, None
        if trace is not None:
            if self.notifier is not None:
                self.notifier.remove_listener(trace)
            trace.stop()

    def send_message(self, can_id: int, data: bytes, remote: bool = False) -> None:
        if not self.bus:
            raise BusError("the master's CAN bus is closed")
        msg = can.Message(arbitration_id=can_id, data=data, is_extended_id=False,
                          is_remote_frame=remote, is_rx=False, channel=self.channel)
        try:
            with self.send_lock:
                self.bus.send(msg)
        except can.CanError as exc:
            raise BusError(f"cannot send frame 0x{can_id:03X}: {exc}") from exc
        trace = self.trace
        if trace is not None:
            trace.sent(msg)
