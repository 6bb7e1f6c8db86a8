"""Raw traffic of a run, in a standard python-can log format chosen by suffix.

``.log`` (candump), ``.asc`` (Vector ASCII) or ``.blf`` (Vector binary). Frames the master
receives come from the bus reader thread; frames it sends are logged by the sender.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import can

from stand.errors import InputError

TRACE_SUFFIXES = (".log", ".asc", ".blf")


class Trace(can.Listener):
    """A thread-safe writer of one trace file."""

    def __init__(self, path: str | Path, echoed: tuple[int, ...] = ()) -> None:
        #: 11-bit ids the master's bus hands back to it (its own frames): not logged twice.
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
        if not msg.is_extended_id and msg.arbitration_id in self.echoed:
            return  # the bus echoing a frame the master sent: logged by :meth:`sent`
        self._log(msg)

    def _log(self, msg: can.Message) -> None:
        with self._lock:
            if self._closed:
                return
            self._writer.on_message_received(msg)
            self.frames += 1

    def sent(self, msg: can.Message) -> None:
        """Log a frame the master sent (stamped now)."""
        msg.timestamp = time.time()
        self._log(msg)

    def stop(self) -> None:
        with self._lock:
            if not self._closed:
                self._closed = True
                self._writer.stop()
