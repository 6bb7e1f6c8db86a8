"""Everything CAN and CANopen; the only package that imports ``can`` or ``canopen``.

Modules, each named after its CiA concept:

- :mod:`bus.adapters` — python-can buses chosen by name (``virtual``, ``socketcan``, ...).
- :mod:`bus.eds` — object dictionaries from EDS files; raw process data ↔ SI units.
- :mod:`bus.pdo` — PDO mapping entries and their packing.
- :mod:`bus.cia402` — controlword, statusword, the drive state machine, modes.
- :mod:`bus.drive_node` — a simulated CiA 402 drive (canopen LocalNode + stand physics).
- :mod:`bus.simstand` — the simulated drives of a profile (``python -m bus.simstand``).
- :mod:`bus.drive` — the master's proxy of one drive (SDO, PDO mapping, enabling).
- :mod:`bus.heartbeat` — heartbeat and EMCY consumer.
- :mod:`bus.sync` — SYNC counter, real-time clock, jitter.
- :mod:`bus.sampler` — SYNC-aligned sample buffers with gap accounting.
- :mod:`bus.trace` — raw traffic logs (candump ``.log``, ``.asc``, ``.blf``).
- :mod:`bus.master` — the master: boot, configure, supervise, run the SYNC loop.
- :mod:`bus.stand_bus` — master (+ simulated drives) as the stand controller sees it.
"""
