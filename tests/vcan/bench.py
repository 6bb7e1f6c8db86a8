"""Figures of the real SocketCAN bus on vcan0 (run by tests/vcan/run.sh after the tests).

    python -m tests.vcan.bench          # inside User-Mode Linux, or on any host with vcan0

Prints frames/s between two python-can sockets, frames/s that python-can receives from
cangen at full speed, the rate ``cangen -g 1`` really reaches, and the SYNC jitter of our
master in realtime mode at 1 ms and 15 ms, with the simulated drives in their own process:
p50/p99/max of |interval - period| both as the master timed its sends (time.monotonic) and
as candump's kernel timestamps saw the SYNCs arrive.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import can
import numpy as np

from tests.vcan.canutils import Candump, Cangen
from tests.vcan.conftest import CHANNEL, VCAN_SYSFS, SimstandProcess

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
            start = last = time.perf_counter()
            while got < frames and rx.recv(0.5) is not None:
                got += 1
                last = time.perf_counter()
        return got / (last - start), got
    finally:
        rx.shutdown()


def cangen_gap_fps(gap_ms: float = 1.0, duration_s: float = 2.0) -> float:
    """Frames/s that ``cangen -g gap_ms`` really makes here (timer resolution of the guest)."""
    rx = can.Bus(interface="socketcan", channel=CHANNEL)
    try:
        got = 0
        with Cangen(CHANNEL, gap_ms=gap_ms, ident="555"):
            start = time.perf_counter()
            while time.perf_counter() - start < duration_s:
                if rx.recv(0.1) is not None:
                    got += 1
        return got / duration_s
    finally:
        rx.shutdown()


JITTER_PROFILE = "crouzet_82800502"
#: (period, samples): 1 ms as the fast stands (seed 001, the two-motor stand), 15 ms as seed 000.
JITTER_CASES = ((0.001, 2000), (0.015, 300))


def sync_jitter(period_s: float, samples: int) -> str:
    """One realtime run of the master against the drives' process; the jitter line."""
    from bus.adapters import BusConfig
    from bus.drive import DriveConfig
    from bus.master import Master
    from bus.simstand import scaling_for
    from bus.sync import Jitter
    from stand.profiles import load_motor

    scaling = scaling_for(load_motor(JITTER_PROFILE))
    with tempfile.TemporaryDirectory() as tmp:
        drives = SimstandProcess(JITTER_PROFILE, Path(tmp) / "simstand.log")
        try:
            drives.wait_ready()
            master = Master(BusConfig("socketcan", CHANNEL), heartbeat_period_s=0.5)
            try:
                master.setup([DriveConfig(1, "speed", scaling)], period_s)
                with Candump(CHANNEL) as dump:
                    run = master.run(np.full((1, samples), 10.0), time_mode="realtime")
                master.stop_drives()
            finally:
                master.close()
        finally:
            drives.close()
    wire = np.array([f.timestamp_s for f in dump.frames
                     if f.arbitration_id == 0x080 and not f.is_extended_id][:run.count])
    # SYNCs come from the kernel's broadcast manager (the master's default on SocketCAN):
    # the master's figure is the stamps of the SYNCs as its socket handed them on.
    heard = run.sync_stamp_s[np.isfinite(run.sync_stamp_s)]
    sent, seen = Jitter.of(heard, period_s), Jitter.of(wire, period_s)
    d = run.drives[0]
    return (f"vcan bench: SYNC jitter at {period_s * 1e3:g} ms, {run.count} SYNCs"
            f"{' (aborted: ' + run.aborted + ')' if run.aborted else ''}: "
            f"master heard p50/p99/max {_us(sent)}, on the wire (candump) {_us(seen)}; "
            f"TPDOs lost {d.lost} of {2 * run.count}, duplicates {d.duplicates}")


def _us(j: Any) -> str:
    return f"{j.p50_s * 1e6:.0f}/{j.p99_s * 1e6:.0f}/{j.max_s * 1e6:.0f} us"


def main() -> int:
    if not VCAN_SYSFS.exists():
        print(f"bench: {VCAN_SYSFS} missing; run tests/vcan/run.sh", file=sys.stderr)
        return 1
    print(f"vcan bench: python-can -> python-can on {CHANNEL}: {python_to_python_fps():,.0f} frames/s")
    fps, got = cangen_to_python_fps()
    print(f"vcan bench: cangen -g 0 -> python-can on {CHANNEL}: {fps:,.0f} frames/s "
          f"({got} of {THROUGHPUT_FRAMES} received)")
    print(f"vcan bench: cangen -g 1 makes {cangen_gap_fps(1.0):,.0f} frames/s here (1,000 asked)")
    failed = 0
    for period_s, samples in JITTER_CASES:
        try:
            print(sync_jitter(period_s, samples))
        except Exception as exc:  # one failed case must not hide the others' figures
            print(f"vcan bench: SYNC jitter at {period_s * 1e3:g} ms failed: {exc!r}")
            failed += 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
