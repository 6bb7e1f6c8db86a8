"""SYNC producer (CiA 301 §7.2.5) with the counter of 0x1019, and the two time modes.

- ``lockstep``: the next SYNC goes out as soon as every drive answered the last one, and
  simulated drives advance exactly one period per SYNC: deterministic, as fast as the bus.
- ``realtime``: SYNCs follow a wall-clock period (deadlines on ``time.monotonic()``; the
  last stretch before a deadline is spent in ``time.sleep(0)``, which keeps the jitter low
  and still lets the bus reader threads have the interpreter).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from bus.cia301 import SYNC_COB_ID
from stand.errors import ForeignSync, InputError

__all__ = ["SYNC_COB_ID", "SyncCounter", "SyncWatch", "RealtimeClock", "Jitter", "check_time_mode"]
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

    ``echo``: the master hears its own SYNCs (they come back in the order sent, carrying the
    counter sequence from ``first``); without echo, every SYNC heard is another producer's.
    A SYNC out of the sequence, of another length, or beyond the count sent is foreign.
    Subscribe :meth:`on_sync` to 0x080; :meth:`sent` before each SYNC leaves.
    """

    def __init__(self, echo: bool, first: int, overflow: int = SYNC_COUNTER_OVERFLOW) -> None:
        self.echo = echo
        self.overflow = overflow
        self.expected = first
        self.sent_count = 0
        self.heard = 0
        self.foreign = 0
        self.first_foreign: bytes | None = None

    def sent(self) -> None:
        self.sent_count += 1

    def on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """Subscriber of 0x080 (bus reader thread)."""
        ours = self.echo and self.heard < self.sent_count and (
            bytes(data[:1]) == (bytes([self.expected]) if self.overflow else b"")
            and len(data) == (1 if self.overflow else 0))
        if ours:
            self.heard += 1
            if self.overflow:
                self.expected = self.expected % self.overflow + 1
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
