"""SYNC producer (CiA 301 §7.2.5) with the counter of 0x1019, and the two time modes.

- ``lockstep``: the next SYNC goes out as soon as every drive answered the last one, and
  simulated drives advance exactly one period per SYNC: deterministic, as fast as the bus.
- ``realtime``: SYNCs follow a period. Where the bus has kernel timers (SocketCAN's
  broadcast manager) the kernel sends them (:class:`KernelSync`: one cyclic task over the
  frames of the whole counter sequence, so each SYNC carries its counter), on time however
  busy this process is; the master follows their echoes. Elsewhere the Python clock does
  (:class:`RealtimeClock`: deadlines on ``time.monotonic()``; the last stretch before a
  deadline is spent in ``time.sleep(0)``, which keeps the jitter low and still lets the
  bus reader threads have the interpreter).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import can
import numpy as np

from bus.cia301 import SYNC_COB_ID
from stand.errors import ForeignSync, InputError

__all__ = ["SYNC_COB_ID", "SyncCounter", "SyncWatch", "RealtimeClock", "KernelSync", "Jitter",
           "check_time_mode"]
#: SYNC counter overflow value written to 0x1019 (1..240; 0 = no counter).
SYNC_COUNTER_OVERFLOW = 240
#: Below this much time to a deadline the clock yields instead of sleeping, s.
SPIN_S = 2e-4
TIME_MODES = ("lockstep", "realtime")
#: Real time: synchronous window length 0x1007 as a fraction of the SYNC period. A drive
#: discards a synchronous TPDO it could not send within it, and the master a TPDO stamped
#: after it, so a late answer is never taken for the next SYNC's (CiA 301 §7.5.2.7).
SYNC_WINDOW_FRACTION = 0.5


def check_time_mode(mode: str) -> str:
    if mode not in TIME_MODES:
        raise InputError(f"time_mode must be 'lockstep' or 'realtime', not {mode!r}")
    return mode


class SyncCounter:
    """The counter byte of SYNC frames: 1, 2, ..., overflow, 1, ... (none when 0)."""

    def __init__(self, overflow: int = SYNC_COUNTER_OVERFLOW) -> None:
        if not 0 <= overflow <= 240 or overflow == 1:
            raise InputError(f"SYNC counter overflow must be 0 or 2..240, got {overflow}")
        self.overflow = overflow
        self.value = 0

    def upcoming(self) -> int:
        """The counter value the next SYNC will carry (0 when the counter is off)."""
        return self.value % self.overflow + 1 if self.overflow else 0

    def next(self) -> tuple[int, bytes]:
        """The next counter value and the SYNC frame's data."""
        if not self.overflow:
            return 0, b""
        self.value = self.value % self.overflow + 1
        return self.value, bytes([self.value])


class SyncWatch:
    """Tells the master's own SYNCs from another producer's (CiA 301 allows one producer).

    ``echo``: the master hears its own SYNCs (in the order sent, carrying the counter
    sequence from ``first``); without echo, every SYNC heard is another producer's. A SYNC
    of ours may be missing from what the master's socket hands on (a full receive queue on
    a loaded machine), so one whose counter is ahead of the next expected still counts as
    ours if the master had sent that many: counted out by :meth:`sent`, or with
    ``period_s`` (SYNCs the kernel sends) as many periods as passed since the last one
    heard. Anything else (out of sequence, another length, more than sent) is foreign.
    Subscribe :meth:`on_sync` to 0x080.
    """

    def __init__(self, echo: bool, first: int, overflow: int = SYNC_COUNTER_OVERFLOW,
                 period_s: float | None = None) -> None:
        self.echo = echo
        self.overflow = overflow
        #: The kernel's period when it sends the SYNCs (the master does not count them out).
        self.period_s = period_s
        self.expected = first
        self.sent_count = 0
        self.heard = 0
        self.unheard = 0  # SYNCs of ours the socket did not hand on
        self._last_stamp: float | None = None
        self.foreign = 0
        self.first_foreign: bytes | None = None

    def sent(self) -> None:
        self.sent_count += 1

    def _may_skip(self, timestamp: float) -> int:
        """How many of our SYNCs may have gone unheard before one stamped ``timestamp``."""
        if self.period_s is None:
            return self.sent_count - self.heard - 1
        if self._last_stamp is None:
            return 0
        return int(round((timestamp - self._last_stamp) / self.period_s)) - 1

    def on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """Subscriber of 0x080 (bus reader thread)."""
        if self.echo and len(data) == (1 if self.overflow else 0):
            skipped = (data[0] - self.expected) % self.overflow if self.overflow else 0
            if skipped <= self._may_skip(timestamp):
                self.heard += 1 + skipped
                self.unheard += skipped
                self._last_stamp = timestamp
                if self.overflow:
                    self.expected = data[0] % self.overflow + 1
                return
        self.foreign += 1
        if self.first_foreign is None:
            self.first_foreign = bytes(data)

    def error(self) -> ForeignSync | None:
        """The first foreign SYNC as an error, or None."""
        if not self.foreign:
            return None
        data = self.first_foreign.hex(" ") if self.first_foreign else "no data"
        return ForeignSync(f"{self.foreign} SYNC frame(s) on 0x080 that this master did not send "
                           f"(first: {data}); another SYNC producer is on the bus; every drive "
                           "was quick-stopped")


class RealtimeClock:
    """Wall-clock deadlines every ``period_s`` seconds from the first :meth:`wait`.

    After a late tick the next one still keeps ``min_interval_s`` from it (so that two SYNCs
    never come closer than the synchronous window); later ticks keep the original grid.
    """

    def __init__(self, period_s: float, min_interval_s: float = 0.0) -> None:
        self.period_s = period_s
        self.min_interval_s = min_interval_s
        self.start: float | None = None
        self.last = 0.0
        self.k = 0

    def wait(self) -> float:
        """Wait for the next deadline; return ``time.monotonic()`` when it was reached."""
        now = time.monotonic()
        if self.start is None:
            self.start = self.last = now
            self.k = 1
            return now
        deadline = max(self.start + self.k * self.period_s, self.last + self.min_interval_s)
        self.k += 1
        remaining = deadline - now
        if remaining > SPIN_S:
            time.sleep(remaining - SPIN_S)
        while (now := time.monotonic()) < deadline:
            time.sleep(0)
        self.last = now
        return now


class KernelSync:
    """SYNCs from the kernel's broadcast manager: one cyclic task over the counter's frames.

    Parameters
    ----------
    bus : can.BusABC
        A bus with kernel timers (SocketCAN).
    period_s : float
        SYNC period, s.
    counter : SyncCounter
        The master's counter; the task's frames start at its next value and run through
        the whole sequence (the kernel sends them in turn, one a period). After :meth:`stop`
        the counter is set to the last value heard on the bus, as if the master had sent
        every SYNC itself.

    Subscribe :meth:`on_sync` to 0x080 (the master hears the kernel's SYNCs as any frame).
    """

    def __init__(self, bus: can.BusABC, period_s: float, counter: SyncCounter) -> None:
        self.bus = bus
        self.period_s = period_s
        self.counter = counter
        first, overflow = counter.upcoming(), counter.overflow
        values = ([(first - 1 + i) % overflow + 1 for i in range(overflow)] if overflow else [0])
        self.frames = [can.Message(arbitration_id=SYNC_COB_ID, is_extended_id=False,
                                   data=bytes([v]) if overflow else b"") for v in values]
        self.task: can.CyclicSendTaskABC | None = None
        self._heard = threading.Condition()
        self.heard = 0
        self.last: tuple[int, float] | None = None  # (counter, bus stamp) of the newest

    def start(self) -> None:
        self.task = self.bus.send_periodic(self.frames, self.period_s)

    def on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """Subscriber of 0x080 (bus reader thread)."""
        with self._heard:
            self.heard += 1
            self.last = (data[0] if data else 0, timestamp)
            self._heard.notify_all()

    def wait(self, count: int, timeout_s: float) -> tuple[int, float] | None:
        """Wait until ``count`` SYNCs were heard; the newest's (counter, stamp), or None."""
        with self._heard:
            if not self._heard.wait_for(lambda: self.heard >= count, timeout_s):
                return None
            return self.last

    def before_window(self, k: int, answered: threading.Event, window_s: float,
                      timeout_s: float) -> float | None:
        """Wait until window ``k`` may be prepared: SYNC k-1 heard, and its answers in
        (``answered`` set) or its synchronous window ``window_s`` over. Return
        ``time.monotonic()`` then, or None when SYNC k-1 was not heard within ``timeout_s``."""
        if k == 0:
            return time.monotonic()
        heard = self.wait(k, timeout_s)
        if heard is None:
            return None
        closes = heard[1] + window_s - time.time()  # bus stamps count on time.time()
        if closes > 0:
            answered.wait(min(closes, timeout_s))
        return time.monotonic()

    def stop(self) -> None:
        """Stop the task; the counter goes on from the last SYNC heard (one period later)."""
        task, self.task = self.task, None
        if task is None:
            return
        task.stop()
        time.sleep(self.period_s)  # the echo of a SYNC sent just before the stop
        with self._heard:
            if self.last is not None and self.counter.overflow:
                self.counter.value = self.last[0]


@dataclass(frozen=True)
class Jitter:
    """SYNC period jitter: deviation of the intervals between SYNCs from the period, s."""

    period_s: float
    p50_s: float
    p99_s: float
    max_s: float
    samples: int

    @classmethod
    def of(cls, send_times_s: np.ndarray, period_s: float) -> Jitter:
        deviation = np.abs(np.diff(send_times_s) - period_s)
        if deviation.size == 0:
            return cls(period_s, 0.0, 0.0, 0.0, 0)
        return cls(period_s, float(np.percentile(deviation, 50)), float(np.percentile(deviation, 99)),
                   float(deviation.max()), int(deviation.size))
