"""Raw traffic of a run, in a standard python-can log format chosen by suffix.

``.log`` (candump), ``.asc`` (Vector ASCII) or ``.blf`` (Vector binary). Frames the master
receives come from the bus reader thread; frames it sends are logged by the sender, the
master's :class:`MasterNetwork`.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import can
import canopen

from stand.errors import BusError, InputError

TRACE_SUFFIXES = (".log", ".asc", ".blf")


class Trace(can.Listener):
    """A thread-safe writer of one trace file."""

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

    def on_message_received(self, msg: can.Message) -> None:
        self._log(msg)

    def _log(self, msg: can.Message) -> None:
        with self._lock:
            if self._closed:
                return
            self._writer.on_message_received(msg)
            self.frames += 1

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
                self._writer.stop()


class MasterNetwork(canopen.Network):
    """A canopen network that also logs the frames it sends to the run's trace."""

    trace: Trace | None = None
    channel: str | None = None

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
