"""Raw traffic of a run, in a standard python-can log format chosen by suffix.

``.log`` (candump), ``.asc`` (Vector ASCII) or ``.blf`` (Vector binary). Frames the master
receives come from the bus reader thread; frames it sends are logged by the sender, the
master's :class:`MasterNetwork`.
"""

from __future__ import annotations

import contextlib
import threading
import time
from pathlib import Path

import can
import canopen

from stand.errors import BusError, InputError, StorageError

TRACE_SUFFIXES = (".log", ".asc", ".blf")


class Trace(can.Listener):
    """A thread-safe writer of one trace file.

    A write that fails (a full disk, a file system gone) ends the trace, never the caller:
    frames come from python-can's bus reader thread, which an exception would end, and with
    it every SDO answer, heartbeat and EMCY the master needs to stop the drives. The
    failure is kept in :attr:`error` for the run to act on.
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
        self._lock = threading.Lock()
        self.frames = 0
        self._closed = False
        #: Why the trace ended early, or None.
        self.error: StorageError | None = None

    def on_message_received(self, msg: can.Message) -> None:
        self._log(msg)

    def _log(self, msg: can.Message) -> None:
        with self._lock:
            if self._closed:
                return
            try:
                self._writer.on_message_received(msg)
            except Exception as exc:  # any exception would end the bus reader
                self._fail(exc)
                return
            self.frames += 1

    def _fail(self, exc: Exception) -> None:
        """End the trace after a failed write (lock held)."""
        self._closed = True
        self.error = StorageError(f"cannot write trace file {self.path}: {exc}; the trace ends "
                                  f"after {self.frames} frames")
        with contextlib.suppress(Exception):  # the file is already lost; closing is best effort
            self._writer.stop()

    def sent(self, msg: can.Message) -> None:
        """Log a frame the master sent (stamped now), unless the bus hands it back."""
        if not msg.is_extended_id and msg.arbitration_id in self.echoed:
            return
        msg.timestamp = time.time()
        self._log(msg)

    def stop(self) -> None:
        with self._lock:
            if not self._closed:
                self._closed = True
                try:
                    self._writer.stop()  # the last buffered frames are written now
                except Exception as exc:  # reported as a failed write is
                    self._fail(exc)


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
