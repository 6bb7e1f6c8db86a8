"""Bus benchmarks (issue 3, done 2 and 3); prints figures, not collected by pytest.

1. Lockstep: the two-motor stand (2 drives), 1 kHz SYNC, 60 s of stand time: lost
   samples (must be 0), sustained frames/s, stand time / wall time.
2. Real time: SYNC period jitter (p50, p99, max of |interval − period|) at 1 ms and 15 ms,
   for each SYNC producer the bus offers (``python``: the master's clock; ``kernel``:
   SocketCAN's broadcast manager): the producer alone, measured on the wire (the bus stamps
   another socket receives), and a real-time run of the two simulated drives (the stamps of
   the SYNCs as the master heard them; on an interface without echo, when ``send`` returned).

    python tests/bench/bench_bus.py                        # virtual bus, drives in-process
    python tests/bench/bench_bus.py --interface socketcan --channel vcan0   # inside UML
"""

from __future__ import annotations

import argparse
import sys
import threading
import time

import can
import numpy as np

from bus.adapters import BusConfig, has_kernel_timers
from bus.stand_bus import StandBus
from bus.sync import Jitter
from stand.controller import ExperimentProfile, plan

STAND = "cycloidal_two_motor"
#: Frames per SYNC on the two-motor stand: SYNC, 2 RPDOs, 2 × 2 TPDOs.
FRAMES_PER_SYNC = 7


def lockstep(config: BusConfig, duration_s: float) -> dict[str, float]:
    experiment = ExperimentProfile(name="bench", procedure="efficiency", stand=STAND,
                                   duration_s=duration_s, period_s=1e-3)
    (procedure, drives), = plan(experiment)
    targets = np.vstack([port.values for port in procedure.commands])
    with StandBus(STAND, config, simulate=True, seed=0) as bus:
        bus.setup(drives, procedure.sample_period_s)
        started = time.monotonic()
        samples = bus.run(targets, time_mode="lockstep")
        wall = time.monotonic() - started
        bus.stop_drives()
    lost = sum(d.lost for d in samples.drives)
    if samples.aborted:
        print(f"lockstep run aborted: {samples.aborted}")
    return {"syncs": samples.count, "lost_pdos": lost, "wall_s": wall,
            "frames_per_s": FRAMES_PER_SYNC * samples.count / wall,
            "stand_over_wall": samples.count * procedure.sample_period_s / wall}


def realtime(config: BusConfig, period_s: float, syncs: int, producer: str) -> tuple[Jitter, int, int]:
    experiment = ExperimentProfile(name="bench", procedure="efficiency", stand=STAND,
                                   duration_s=syncs * period_s, period_s=period_s)
    (procedure, drives), = plan(experiment)
    targets = np.vstack([port.values for port in procedure.commands])
    with StandBus(STAND, config, simulate=True, seed=0, sync_producer=producer) as bus:
        bus.setup(drives, period_s)
        samples = bus.run(targets, time_mode="realtime")
        bus.stop_drives()
    if samples.aborted:
        print(f"realtime run aborted: {samples.aborted}")
    stamps = samples.sync_stamp_s[np.isfinite(samples.sync_stamp_s)]
    return (Jitter.of(stamps, period_s), sum(d.lost for d in samples.drives),
            sum(d.late + d.duplicates for d in samples.drives))


def sync_only(config: BusConfig, period_s: float, syncs: int, producer: str) -> Jitter:
    """Jitter of the SYNC producer alone (nothing else in the process), on the wire: the bus
    stamps of the SYNCs another socket receives."""
    from bus.sync import SYNC_COB_ID, KernelSync, RealtimeClock, SyncCounter

    rx = can.Bus(interface=config.interface, channel=config.channel,
                 can_filters=[{"can_id": SYNC_COB_ID, "can_mask": 0x7FF, "extended": False}])
    tx = can.Bus(interface=config.interface, channel=config.channel)
    stamps: list[float] = []

    def receive() -> None:
        while len(stamps) < syncs:
            msg = rx.recv(1.0)
            if msg is None:
                return
            stamps.append(msg.timestamp)

    reader = threading.Thread(target=receive, name="bench-sync-rx")
    reader.start()
    try:
        counter = SyncCounter()
        if producer == "kernel":
            kernel = KernelSync(tx, period_s, counter)
            kernel.start()
            reader.join()
            kernel.stop()
        else:
            clock = RealtimeClock(period_s)
            for _ in range(syncs):
                clock.wait()
                tx.send(can.Message(arbitration_id=SYNC_COB_ID, data=counter.next()[1],
                                    is_extended_id=False))
            reader.join()
    finally:
        tx.shutdown()
        rx.shutdown()
    return Jitter.of(np.array(stamps), period_s)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--interface", default="virtual")
    parser.add_argument("--channel", default="bench-bus")
    parser.add_argument("--duration", type=float, default=60.0, help="lockstep stand time, s")
    parser.add_argument("--realtime-s", type=float, default=10.0, help="wall time per jitter run, s")
    parser.add_argument("--skip-lockstep", action="store_true")
    args = parser.parse_args(argv)
    config = BusConfig(args.interface, args.channel)
    print(f"bus: {config.interface}:{config.channel}")
    ok = True
    if not args.skip_lockstep:
        r = lockstep(config, args.duration)
        ok &= r["lost_pdos"] == 0 and r["syncs"] == round(args.duration / 1e-3)
        print(f"lockstep, 2 drives, 1 kHz SYNC, {args.duration:g} s stand time: {r['syncs']:.0f} SYNCs, "
              f"lost TPDOs {r['lost_pdos']:.0f}, wall {r['wall_s']:.2f} s, "
              f"{r['frames_per_s']:.0f} frames/s, stand/wall {r['stand_over_wall']:.2f}")
    probe = can.Bus(interface=config.interface, channel=config.channel)
    producers = ["python"] + (["kernel"] if has_kernel_timers(probe) else [])
    probe.shutdown()
    for period in (1e-3, 15e-3):
        for producer in producers:
            jitter = sync_only(config, period, int(args.realtime_s / period), producer)
            print(f"realtime SYNC {period * 1e3:g} ms from the {producer} producer alone, on the wire "
                  f"({jitter.samples} intervals): jitter {_us(jitter)}")
            jitter, lost, late = realtime(config, period, int(args.realtime_s / period), producer)
            print(f"realtime SYNC {period * 1e3:g} ms from the {producer} producer, 2 drives simulated "
                  f"in-process ({jitter.samples} intervals): jitter {_us(jitter)}; lost TPDOs {lost}, "
                  f"late or duplicate {late}")
    return 0 if ok else 1


def _us(j: Jitter) -> str:
    return f"p50 {j.p50_s * 1e6:.0f} µs, p99 {j.p99_s * 1e6:.0f} µs, max {j.max_s * 1e6:.0f} µs"


if __name__ == "__main__":
    sys.exit(main())
