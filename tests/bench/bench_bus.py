"""Bus benchmarks (issue 3, done 2 and 3); prints figures, not collected by pytest.

1. Lockstep: the two-motor stand (2 drives), 1 kHz SYNC, 60 s of stand time: lost
   samples (must be 0), sustained frames/s, stand time / wall time.
2. Real time: SYNC period jitter (p50, p99, max of |interval − period|) at 1 ms and 15 ms.

    python tests/bench/bench_bus.py                        # virtual bus, drives in-process
    python tests/bench/bench_bus.py --interface socketcan --channel vcan0   # inside UML
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from bus.adapters import BusConfig
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


def realtime(config: BusConfig, period_s: float, syncs: int) -> tuple[Jitter, int]:
    experiment = ExperimentProfile(name="bench", procedure="efficiency", stand=STAND,
                                   duration_s=syncs * period_s, period_s=period_s)
    (procedure, drives), = plan(experiment)
    targets = np.vstack([port.values for port in procedure.commands])
    with StandBus(STAND, config, simulate=True, seed=0) as bus:
        bus.setup(drives, period_s)
        samples = bus.run(targets, time_mode="realtime")
        bus.stop_drives()
    if samples.aborted:
        print(f"realtime run aborted: {samples.aborted}")
    return Jitter.of(samples.wall_s, period_s), sum(d.lost for d in samples.drives)


def sync_only(config: BusConfig, period_s: float, syncs: int) -> Jitter:
    """Jitter of the SYNC producer alone (no drives, nothing else in the process)."""
    from bus.adapters import connect_network
    from bus.sync import SYNC_COB_ID, RealtimeClock, SyncCounter

    network = connect_network(config)
    try:
        clock, counter = RealtimeClock(period_s), SyncCounter()
        sent = np.empty(syncs)
        for k in range(syncs):
            sent[k] = clock.wait()
            network.send_message(SYNC_COB_ID, counter.next()[1])
    finally:
        network.disconnect()
    return Jitter.of(sent, period_s)


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
    for period in (1e-3, 15e-3):
        jitter = sync_only(config, period, int(args.realtime_s / period))
        print(f"realtime SYNC {period * 1e3:g} ms, SYNC producer alone ({jitter.samples} intervals): "
              f"jitter p50 {jitter.p50_s * 1e6:.0f} µs, p99 {jitter.p99_s * 1e6:.0f} µs, "
              f"max {jitter.max_s * 1e6:.0f} µs")
        jitter, lost = realtime(config, period, int(args.realtime_s / period))
        print(f"realtime SYNC {period * 1e3:g} ms, 2 drives simulated in-process "
              f"({jitter.samples} intervals): jitter "
              f"p50 {jitter.p50_s * 1e6:.0f} µs, p99 {jitter.p99_s * 1e6:.0f} µs, "
              f"max {jitter.max_s * 1e6:.0f} µs; lost TPDOs {lost}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
