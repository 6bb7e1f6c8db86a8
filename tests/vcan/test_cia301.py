"""The frame readers of tests/vcan/cia301.py refuse what CiA 301 forbids (no bus needed).

They are the judge of test_master.py, so they are shown here to catch the faults they exist
to catch: a SYNC counter that jumps or is missing, an unanswered or crossed SDO, a PDO
mapping changed while the PDO is valid, a master sample taken from the wrong SYNC.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.vcan import cia301
from tests.vcan.canutils import Frame, parse_candump_line

NEEDS_VCAN = False


def frames(*lines: str) -> list[Frame]:
    out = []
    for n, line in enumerate(lines):
        frame = parse_candump_line(f"({n / 1000:.6f}) vcan0 {line}")
        assert frame is not None, line
        out.append(frame)
    return out


def test_parse_candump_line() -> None:
    f = parse_candump_line("(1700000000.123456) vcan0 1ABCDE00#0102")
    assert f is not None
    assert (f.arbitration_id, f.is_extended_id, f.data) == (0x1ABCDE00, True, b"\x01\x02")
    r = parse_candump_line("(1.0) vcan0 080#R")
    assert r is not None and r.is_remote_frame and r.arbitration_id == 0x80
    assert parse_candump_line("(1.0) vcan0 123##1AA") is None


def test_sync_counter_wraps_and_may_restart() -> None:
    assert cia301.check_sync(frames("080#01", "080#02", "080#03", "080#01", "080#02"), 3) == [1, 2, 3, 1, 2]
    assert cia301.check_sync(frames("080#", "080#"), 0) == [0, 0]


@pytest.mark.parametrize("lines", [("080#01", "080#03"),        # a jump
                                   ("080#01", "080#"),          # counter missing
                                   ("080#05",),                 # beyond the overflow value
                                   ("080#0102",)])              # two data bytes
def test_sync_violations_are_refused(lines: tuple[str, ...]) -> None:
    with pytest.raises(cia301.ProtocolViolation):
        cia301.check_sync(frames(*lines), 4)


def test_sdo_pairs_and_values() -> None:
    transfers = cia301.sdo_transfers(frames(
        "601#2B17100064000000", "581#6017100000000000",      # write 0x1017 = 100 (2 bytes)
        "601#4000180100000000", "581#4300180181010000",      # read 0x1800:01 = 0x181
        "601#2F60600009000000", "581#8060600030000906"), 1)  # write 0x6060, aborted
    assert [(t.write, t.index, t.subindex, t.value) for t in transfers[:2]] == [
        (True, 0x1017, 0, 100), (False, 0x1800, 1, 0x181)]
    assert transfers[2].abort_code == 0x06090030


@pytest.mark.parametrize("lines", [("601#2B17100064000000", "601#2B17100064000000"),   # two at once
                                   ("581#6017100000000000",),                          # no request
                                   ("601#2B17100064000000", "581#6018100000000000"),   # other object
                                   ("601#2B171000640000",),                            # 7 bytes
                                   ("601#2B17100064000000",)])                         # no answer
def test_sdo_violations_are_refused(lines: tuple[str, ...]) -> None:
    with pytest.raises(cia301.ProtocolViolation):
        cia301.sdo_transfers(frames(*lines), 1)


def _write(index: int, sub: int, value: int) -> tuple[str, str]:
    data = bytes([0x23]) + index.to_bytes(2, "little") + bytes([sub]) + value.to_bytes(4, "little")
    return f"601#{data.hex().upper()}", f"581#60{data[1:4].hex().upper()}00000000"


def test_pdo_mapping_procedure() -> None:
    good = [*_write(0x1800, 1, 0x8000_0181), *_write(0x1A00, 0, 0), *_write(0x1A00, 1, 0x60640020),
            *_write(0x1A00, 0, 1), *_write(0x1800, 2, 1), *_write(0x1800, 1, 0x181)]
    pdo = cia301.pdo_configs(cia301.sdo_transfers(frames(*good), 1))[0x1800]
    assert (pdo.cob_id, pdo.transmission_type, pdo.mapping, pdo.length_bytes) == (
        0x181, 1, ((0x6064, 0, 32),), 4)
    while_valid = good[2:]  # mapping written without invalidating the PDO first
    with pytest.raises(cia301.ProtocolViolation):
        cia301.pdo_configs(cia301.sdo_transfers(frames(*while_valid), 1))


def test_a_sample_from_the_wrong_sync_is_caught() -> None:
    """The misattribution check itself: shifting the master's samples by one window fails."""
    from tests.vcan import test_master as tm

    lines = []
    for k in range(60):
        lines += ["080#01", f"181#{(1000 * k).to_bytes(4, 'little').hex()}0000",
                  f"281#{(50_000).to_bytes(4, 'little').hex()}0000"]
    wire = frames(*lines)

    class FakeSamples:
        count = 60

        def __init__(self, positions: np.ndarray) -> None:
            s = tm.scaling_for(tm.load_motor(tm.PROFILE))
            self.drives = [type("D", (), {"columns": {
                "position_rad": positions * s.rad_per_count, "current_A": np.zeros(60),
                "velocity_rad_s": np.full(60, 50.0)}})()]

    right = 1000.0 * np.arange(60)
    tm._assert_master_read_the_wire(FakeSamples(right), wire)  # type: ignore[arg-type]
    with pytest.raises(AssertionError, match="misattributed"):
        tm._assert_master_read_the_wire(FakeSamples(np.roll(right, 1)), wire)  # type: ignore[arg-type]
