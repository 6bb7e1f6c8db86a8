"""CAN traces back into run files: a run's trace (in the format ``stand run --trace-format``
chooses) read back by ``stand import`` gives the very samples the run wrote (same columns,
bit-equal after the CSV's 9 significant digits), in each of python-can's formats; the
trace's own SDO traffic gives the mapping and the period when it has them; a DBC decodes
frames through cantools.
"""

from __future__ import annotations

import json
from pathlib import Path

import can
import cantools
import numpy as np
import pytest
from numpy.testing import assert_array_equal

from bus import cia402
from bus.adapters import BusConfig
from bus.dbc import decode_dbc
from bus.eds import VELOCITY_UNIT_RAD_S
from bus.simstand import scaling_for
from bus.stand_bus import StandBus
from bus.tracereader import decode_trace, sdo_values
from stand.cli import main
from stand.controller import ExperimentProfile, StandController, plan
from stand.errors import InputError
from stand.importer import import_run
from stand.profiles import load_motor
from stand.runfile import read_run
from stand.sources import ReadOptions

MOTOR = "crouzet_82800502"


#: The run whose trace is read back: one 1 s no-load run (speed mode) at 1 kHz.
NO_LOAD = ExperimentProfile(name="trace", procedure="no_load", motor=MOTOR, repeats=1,
                            duration_s=1.0, period_s=1e-3)
#: Heartbeat period, s: long enough that a loaded machine never starves a heartbeat into an
#: aborted run (heartbeats are tested in test_bus_faults, not here).
CALM_HEARTBEAT_S = 1.0


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One 1 s no-load run on the virtual bus per trace format, as ``stand run`` makes it."""
    out: dict[str, Path] = {}
    for fmt in ("log", "asc", "blf"):
        folder = tmp_path_factory.mktemp(fmt)
        with StandBus(MOTOR, BusConfig("virtual", f"trace-import-{fmt}"), simulate=True, seed=5,
                      heartbeat_period_s=CALM_HEARTBEAT_S) as bus:
            record = StandController(bus, trace_suffix=f".{fmt}").run_experiment(NO_LOAD, folder).runs[0]
        assert record.complete and record.trace_path == str(folder / f"no_load_1.{fmt}")
        out[fmt] = folder
    return out


@pytest.mark.parametrize("fmt", ["log", "asc", "blf"])
@pytest.mark.parametrize("flags", [[], ["--motor", MOTOR, "--period", "0.001"]], ids=["bare", "told"])
def test_a_run_reads_back_exactly_from_its_trace(runs: dict[str, Path], fmt: str, flags: list[str],
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """The trace starts before the setup: its SDO traffic gives the mappings, the period and
    the drive's units, so the import needs no flags (and flags that agree change nothing)."""
    folder = runs[fmt]
    back = folder / f"back{len(flags)}.csv"
    assert main(["import", str(folder / f"no_load_1.{fmt}"), "-o", str(back), "--json", *flags]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["warnings"] == []
    meta = result["file_meta"]
    assert meta["mapping_from"] == {"1": "sdo"} and meta["period_from"] == "sdo 0x1006"
    assert meta["units_from"] == {"1": "given" if flags else "sdo 0x6075 0x608F"}
    recorded, decoded = read_run(folder / "no_load_1.csv"), read_run(back)
    assert sorted(decoded.columns) == sorted(recorded.columns)
    assert len(decoded) == 1000
    for name in recorded.columns:
        assert_array_equal(decoded[name], recorded[name], err_msg=name)


def test_a_speed_run_keeps_the_target_it_was_sent(runs: dict[str, Path]) -> None:
    """The controller writes the speed target of each sample's period as it went over the
    bus (0x60FF in steps of 0.001 rad/s), and the trace's RPDOs give the same back."""
    ((procedure, _),) = plan(NO_LOAD)
    sent = np.array([round(v / VELOCITY_UNIT_RAD_S) for v in procedure.commands[0].values])
    assert procedure.commands[0].mode == "speed" and np.ptp(sent) > 1000  # a varying target
    recorded = read_run(runs["log"] / "no_load_1.csv")
    np.testing.assert_allclose(recorded["speed_target_rad_s"], sent * VELOCITY_UNIT_RAD_S,
                               rtol=1e-9, atol=0)  # the CSV's 9 significant digits
    decoded = decode_trace(runs["log"] / "no_load_1.log", scaling=scaling_for(load_motor(MOTOR)))
    assert_array_equal(decoded.samples.drives[0].columns["speed_target_rad_s"],
                       sent * VELOCITY_UNIT_RAD_S)


def test_a_trace_without_the_setup_decodes_with_the_masters_mapping_and_warns(
        runs: dict[str, Path], tmp_path: Path) -> None:
    """A trace begun after the SDO setup (candump started late): the master's own mapping,
    the period from the SYNC stamps and the default units, each with a warning."""
    path = tmp_path / "late.log"
    with can.Logger(str(path)) as logger:
        for msg in can.LogReader(str(runs["log"] / "no_load_1.log")):
            if not 0x580 <= msg.arbitration_id < 0x680:  # no SDO traffic
                logger.on_message_received(msg)
    run = import_run(path, [], "single")
    assert run.meta["file_meta"]["mapping_from"] == {1: "motorstand master"}
    assert run.meta["file_meta"]["units_from"] == {1: "default"}
    warnings = " ".join(run.meta["warnings"])
    assert "wall time" in warnings and "default scaling" in warnings
    recorded = read_run(runs["log"] / "no_load_1.csv")
    # in memory against the run file's 9 significant digits; RPDO1 of 6 bytes is speed mode's
    np.testing.assert_allclose(run["speed_target_rad_s"], recorded["speed_target_rad_s"],
                               rtol=1e-9, atol=0)
    told = import_run(path, [], "single", options=ReadOptions(motor=MOTOR, period_s=1e-3))
    np.testing.assert_allclose(told["position_rad"], recorded["position_rad"], rtol=1e-8, atol=0)


def test_short_tpdos_are_left_out_with_a_warning_not_misread(runs: dict[str, Path],
                                                            tmp_path: Path) -> None:
    """A TPDO shorter than its mapping (a foreign drive's or a broken frame) is not unpacked
    into garbage nor a crash: its sample is left out like a lost one, and the import says
    how many there were."""
    path = tmp_path / "short.log"
    cut = set()
    with can.Logger(str(path)) as logger:
        for n, msg in enumerate(can.LogReader(str(runs["log"] / "no_load_1.log"))):
            if msg.arbitration_id == 0x181 and len(cut) < 3 and n % 7 == 0:
                msg = can.Message(timestamp=msg.timestamp, arbitration_id=0x181,
                                  is_extended_id=False, data=bytes(msg.data)[:2])
                cut.add(n)
            logger.on_message_received(msg)
    assert len(cut) == 3
    decoded = decode_trace(path)
    (drive,) = decoded.samples.drives
    assert drive.short == 3 and drive.lost == 3
    assert "node 1: 3 TPDOs shorter than their mapping" in " ".join(decoded.warnings)
    recorded = read_run(runs["log"] / "no_load_1.csv")
    np.testing.assert_allclose(drive.columns["position_rad"][drive.valid],  # the CSV's 9 digits
                               recorded["position_rad"][drive.valid], rtol=1e-8, atol=1e-12)
    with pytest.raises(InputError, match="uniform"):  # a run with gaps is no run file
        import_run(path, [], "single")


def _sdo_download(node: int, index: int, subindex: int, value: int, size: int) -> can.Message:
    command = 0x23 | ((4 - size) << 2)  # expedited download, size indicated
    data = bytes([command]) + index.to_bytes(2, "little") + bytes([subindex]) \
        + value.to_bytes(4, "little")
    return can.Message(arbitration_id=0x600 + node, data=data, is_extended_id=False)


def test_mapping_and_period_come_from_the_traces_sdo_traffic(tmp_path: Path) -> None:
    """A foreign master maps velocity alone into TPDO1 on COB-ID 0x1A5 and sets a 2 ms
    cycle: the decoder must follow those writes, not the defaults."""
    node, cob = 5, 0x1A5
    frames = [
        _sdo_download(node, 0x1006, 0, 2000, 4),
        _sdo_download(node, 0x1800, 1, cob | 0x8000_0000, 4),
        _sdo_download(node, 0x1A00, 0, 0, 1),
        _sdo_download(node, 0x1A00, 1, (cia402.VELOCITY_ACTUAL << 16) | 32, 4),
        _sdo_download(node, 0x1A00, 0, 1, 1),
        _sdo_download(node, 0x1800, 1, cob, 4),
    ]
    # RPDO2 on 0x325 carries the target velocity after the controlword.
    frames += [
        _sdo_download(node, 0x1401, 1, 0x325 | 0x8000_0000, 4),
        _sdo_download(node, 0x1601, 1, (cia402.CONTROLWORD << 16) | 16, 4),
        _sdo_download(node, 0x1601, 2, (cia402.TARGET_VELOCITY << 16) | 32, 4),
        _sdo_download(node, 0x1601, 0, 2, 1),
        _sdo_download(node, 0x1401, 1, 0x325, 4),
    ]
    velocities = [0, 1000, -2500, 40000]  # raw, 1e-3 rad/s each
    targets = {0: 7, 1: -300, 3: 5}  # raw; none sent before SYNC 2: the drive holds -300
    for k, raw in enumerate(velocities):
        if k in targets:
            frames.append(can.Message(arbitration_id=0x325, is_extended_id=False, data=(
                0x0F.to_bytes(2, "little") + targets[k].to_bytes(4, "little", signed=True))))
        frames.append(can.Message(arbitration_id=0x80, data=bytes([k + 1]), is_extended_id=False))
        frames.append(can.Message(arbitration_id=cob, data=raw.to_bytes(4, "little", signed=True),
                                  is_extended_id=False))
    path = tmp_path / "foreign.asc"
    with can.Logger(str(path)) as logger:
        for k, msg in enumerate(frames):
            msg.timestamp = 1000.0 + 1e-4 * k
            logger.on_message_received(msg)
    assert sdo_values(can.LogReader(str(path)))[node][(0x1006, 0)] == 2000
    decoded = decode_trace(path)
    assert decoded.period_s == pytest.approx(2e-3, rel=1e-12)
    assert decoded.period_from == "sdo 0x1006"
    assert decoded.mapping_from == {node: "sdo"}
    assert_array_equal(decoded.samples.drives[0].columns["velocity_rad_s"],
                       np.array(velocities) * 1e-3)
    assert_array_equal(decoded.samples.drives[0].columns["speed_target_rad_s"],
                       np.array([7, -300, -300, 5]) * 1e-3)


def test_dbc_signals_decode_through_cantools(tmp_path: Path) -> None:
    dbc = tmp_path / "drive.dbc"
    dbc.write_text('''VERSION ""
BU_: DRIVE
BO_ 291 Feedback: 4 DRIVE
 SG_ Speed : 0|16@1- (0.01,0) [-300|300] "rad/s" Vector__XXX
 SG_ Current : 16|16@1- (0.001,0) [-30|30] "A" Vector__XXX
''')
    db = cantools.database.load_file(str(dbc))
    path = tmp_path / "dbc.blf"
    with can.Logger(str(path)) as logger:
        for k in range(30):
            data = db.encode_message("Feedback", {"Speed": 0.5 * k, "Current": -0.002 * k})
            logger.on_message_received(can.Message(timestamp=50.0 + 0.01 * k, arbitration_id=291,
                                                   data=data, is_extended_id=False))
    variables = decode_dbc(path, dbc)
    assert_array_equal(variables["Feedback.Speed"], 0.5 * np.arange(30))
    np.testing.assert_allclose(variables["Current"], -0.002 * np.arange(30), rtol=0, atol=1e-12)
    np.testing.assert_allclose(variables["Feedback.t"], 0.01 * np.arange(30), atol=1e-5)  # blf: 10 µs stamps
    with pytest.raises(InputError, match="no frame of the trace is described"):
        decode_dbc(path, _other_dbc(tmp_path))


def _other_dbc(tmp_path: Path) -> Path:
    other = tmp_path / "other.dbc"
    other.write_text('VERSION ""\nBU_: X\nBO_ 1000 Other: 1 X\n SG_ A : 0|8@1+ (1,0) [0|255] "" X\n')
    return other


def test_a_two_drive_run_reads_back_as_a_reducer_run(tmp_path: Path) -> None:
    experiment = ExperimentProfile(name="eff", procedure="efficiency", stand="cycloidal_two_motor",
                                   duration_s=1.0)
    with StandBus("cycloidal_two_motor", BusConfig("virtual", "trace-import-reducer"),
                  simulate=True, seed=5, heartbeat_period_s=CALM_HEARTBEAT_S) as bus:
        record = StandController(bus).run_experiment(experiment, tmp_path).runs[0]
    assert record.complete and record.path is not None and record.trace_path is not None
    back = tmp_path / "back.csv"
    assert main(["import", record.trace_path, "-o", str(back), "--kind", "reducer"]) == 0
    recorded, decoded = read_run(record.path, "reducer"), read_run(back, "reducer")
    assert sorted(decoded.columns) == sorted(recorded.columns)
    for name in recorded.columns:
        assert_array_equal(decoded[name], recorded[name], err_msg=name)
    # One drive of the two is not a reducer run, and the message says how to choose.
    with pytest.raises(InputError, match=r"holds 2 drive\(s\).*give --node"):
        import_run(record.trace_path, [], "single", options=ReadOptions(motor=MOTOR, period_s=1e-3))
    node = import_run(record.trace_path, [], "single",
                      options=ReadOptions(motor=MOTOR, node=2, period_s=record.period_s))
    # in memory against the run file's 9 significant digits
    np.testing.assert_allclose(node["current_A"], recorded["current_out_A"], rtol=1e-8, atol=0)
