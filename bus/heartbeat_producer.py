"""The heartbeat a simulated node produces (CiA 301 §7.2.8.3.2): its NMT state every period.

Where the bus has kernel timers (SocketCAN's broadcast manager) the beat comes from one,
on time however busy this process is, as from a drive's firmware timer; its data is
updated when the NMT state changes. Elsewhere :meth:`HeartbeatProducer.tick` sends it when
due, called from the node's SYNC handler and from the stand's heartbeat thread, whichever
comes first, as drive firmware polls its timers in its main loop.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

import can
import canopen

from bus.adapters import has_kernel_timers
from bus.cia301 import HEARTBEAT_BASE

log = logging.getLogger(__name__)


class HeartbeatProducer:
    """Heartbeats of node ``node_id`` on ``network``, carrying ``state()``.

    Parameters
    ----------
    network : canopen.Network
        The (connected) network of the node.
    node_id : int
        The node's id.
    state : callable
        Returns the node's present NMT state.
    """

    def __init__(self, network: canopen.Network, node_id: int, state: Callable[[], int]) -> None:
        self.network = network
        self.cob_id = HEARTBEAT_BASE + node_id
        self.state = state
        self.muted = False
        self.period_s = 0.0
        self._due = 0.0
        self._lock = threading.Lock()
        self._kernel = has_kernel_timers(network.bus)
        self._task: can.CyclicSendTaskABC | None = None
        self._task_state = -1

    def set_period(self, period_s: float) -> None:
        """Producer heartbeat time 0x1017 was set to ``period_s`` seconds (0: none)."""
        with self._lock:
            self.period_s = period_s
            self._due = time.monotonic() + period_s
            if self._kernel:
                self._stop_task()
                if period_s and not self.muted:
                    state = self.state()
                    bus = self.network.bus
                    assert bus is not None
                    self._task = bus.send_periodic(self._frame(state), period_s)
                    self._task_state = state

    def _frame(self, state: int) -> can.Message:
        return can.Message(arbitration_id=self.cob_id, data=bytes([state]), is_extended_id=False)

    def _stop_task(self) -> None:
        """Stop the kernel's heartbeat task, if any (the lock is held)."""
        task, self._task = self._task, None
        if task is not None:
            try:
                task.stop()
            except (can.CanError, OSError) as exc:  # the bus may be shutting down
                log.debug("0x%03X: stopping the heartbeat task: %s", self.cob_id, exc)

    def stop(self) -> None:
        """Stop the kernel timer until the period is set again (a reset: boot-up comes first)."""
        with self._lock:
            self._stop_task()

    def mute(self) -> None:
        """No more heartbeats (fault injection, or the node closes)."""
        with self._lock:
            self.muted = True
            self._stop_task()

    def refresh(self) -> None:
        """Kernel heartbeat: carry the present NMT state from the next beat on (the timer
        keeps running, so the beats stay one period apart)."""
        with self._lock:
            task, state = self._task, self.state()
            if task is not None and state != self._task_state:
                assert isinstance(task, can.ModifiableCyclicTaskABC)
                task.modify_data(self._frame(state))
                self._task_state = state

    def tick(self, now: float) -> float | None:
        """Send the heartbeat if it is due at ``now``; return when the next one is due.

        With a kernel heartbeat it only keeps the beat's NMT state current (and returns None).
        """
        if self._kernel:
            self.refresh()
            return None
        with self._lock:
            period = self.period_s
            if not period or self.muted:
                return None
            if now >= self._due:
                self.network.send_message(self.cob_id, bytes([self.state()]))
                self._due = max(self._due + period, now)
            return self._due
