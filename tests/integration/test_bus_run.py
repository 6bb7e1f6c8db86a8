"""Experiments over the bus give the same runs as the direct simulation (issue 3, done 1)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import can
import numpy as np
import pytest

from bus.adapters import BusConfig
from bus.stand_bus import StandBus
from stand.cli import main
from stand.cli.run import summarize
from stand.controller import ExperimentProfile, StandController, plan
from stand.errors import LimitError
from stand.ident.efficiency import efficiency
from stand.ident.identify import identify_run
from stand.procedures import simulate_procedure, simulate_stand_procedure
from stand.profiles import load_motor, load_stand
from stand.runfile import CURRENT_MEAN_COLUMN, read_run

#: Heartbeat period of tests that do not test heartbeats: long enough that a one-CPU
#: User-Mode Linux on a loaded host never starves a heartbeat into a false alarm, s.
CALM_HEARTBEAT_S = 0.5
SEED = 7
#: Done criterion 1: bus and direct simulation identify to the same parameters within 1 %.
SAME_PARAMETERS_RTOL = 0.01
#: One encoder count of the 2500-line encoder (4x), rad: the bus may round a position
#: across a count edge where the direct simulation did not (targets travel as integers).
ONE_COUNT_RAD = 2 * math.pi / 10_000
#: Real-time test: samples that must be kept, over all its runs, for the attribution check
#: to mean something (each compared to one encoder count with the direct simulation). 25 in
#: one run was missed once (22 kept) with the host under the guest at load 11.
MIN_KEPT = 10
#: Real-time runs tried until together they keep those: a loaded host made the master late
#: at the very start once (window 2, 1 of 3 samples kept before it), and once a starved
#: master kept no sample of a whole run (its record has no file); every run's kept samples
#: are checked all the same.
REALTIME_ATTEMPTS = 5
#: SYNC period of the first real-time run, s; each run after one that kept too few doubles
#: it (same 100 samples, so 1.5 s up to 24 s), as a lab engineer would slow a starved
#: master down: a fresh CI host once lost 40-76 of 100 TPDOs per drive at 15 ms in all
#: five runs and was late by SYNC 1-14 (2 samples kept at most).
REALTIME_FIRST_PERIOD_S = 0.015
REALTIME_SAMPLES = 100
#: Current travels in per mille of the 1 A rated current: 1 mA steps.
CURRENT_QUANTUM_A = 1e-3


def test_stand_run_identifies_like_direct_simulation(can_config: BusConfig, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", "seed000_no_load", "-o", str(tmp_path), "--json", "--duration", "4",
                 "--seed", str(SEED), "--interface", can_config.interface,
                 "--channel", can_config.channel, "--simulate"])
    assert code == 0
    result = json.loads(capsys.readouterr().out)
    (run,) = result["runs"]
    # the summary names what an incomplete run lost, was late or duplicated, and why it
    # stopped (this failed twice inside User-Mode Linux as a bare `assert (False)`)
    assert run["complete"] and run["samples"] == 4000 and run["lost"] == {"1": 0}, (
        summarize(result))
    assert Path(run["trace_path"]).stat().st_size > 0

    experiment = ExperimentProfile(name="x", procedure="no_load", motor="crouzet_82800502",
                                   repeats=1, duration_s=4.0, period_s=0.001)
    (procedure, _), = plan(experiment)
    direct = simulate_procedure(procedure, load_motor("crouzet_82800502"), seed=SEED,
                                current_mean=True)
    over_bus = read_run(run["path"])
    # Seed 000's model: a smooth function of the data. With effects chosen by the data
    # (the default), a count or a milliampere may tip a test the other way on this
    # forward-only run and move the weakly determined D/J by more than 1 %.
    a, b = identify_run(direct, effects="none"), identify_run(over_bus, effects="none")
    for name in ("Kt_over_J", "D_over_J"):
        assert getattr(b, name) == pytest.approx(getattr(a, name), rel=SAME_PARAMETERS_RTOL), name
    assert np.max(np.abs(over_bus["position_rad"] - direct["position_rad"])) <= ONE_COUNT_RAD * 1.01
    assert np.median(np.abs(over_bus["current_A"] - direct["current_A"])) <= CURRENT_QUANTUM_A
    # the simulated drive's period mean (0x2002) travels in TPDO3, in the same unit
    assert (np.median(np.abs(over_bus[CURRENT_MEAN_COLUMN] - direct[CURRENT_MEAN_COLUMN]))
            <= CURRENT_QUANTUM_A)
    # driven by it, the shipped no-load experiment's speed loop gives Kt/J within 1 %,
    # and the interval holds the simulated motor's (the samples alone miss both, README)
    motor = load_motor("crouzet_82800502").motor
    truth = motor.Kt / motor.J
    result = identify_run(over_bus)
    assert result.current_input == CURRENT_MEAN_COLUMN
    assert result.Kt_over_J == pytest.approx(truth, rel=0.01)
    assert result.Kt_over_J_ci95[0] <= truth <= result.Kt_over_J_ci95[1]


def test_two_drive_efficiency_run_matches_direct_simulation(can_config: BusConfig,
                                                            tmp_path: Path) -> None:
    experiment = ExperimentProfile(name="eff", procedure="efficiency", stand="cycloidal_two_motor",
                                   duration_s=3.0)
    with StandBus("cycloidal_two_motor", can_config, simulate=True, seed=SEED,
                  heartbeat_period_s=CALM_HEARTBEAT_S) as bus:
        record = StandController(bus).run_experiment(experiment, tmp_path).runs[0]
    assert record.complete and record.lost == {1: 0, 2: 0}
    stand = load_stand("cycloidal_two_motor")
    m_in, m_out = load_motor(stand.motor_in), load_motor(stand.motor_out)
    (procedure, _), = plan(experiment)
    direct = simulate_stand_procedure(procedure, stand, m_in, m_out, seed=SEED)
    over_bus = read_run(record.path, "reducer")
    k = m_in.motor.Kt
    eta_direct = efficiency(direct, stand.reducer.ratio, k, k).efficiency
    eta_bus = efficiency(over_bus, stand.reducer.ratio, k, k).efficiency
    assert eta_bus == pytest.approx(eta_direct, rel=SAME_PARAMETERS_RTOL)


def test_voltage_step_run_is_a_step_file(can_config: BusConfig, tmp_path: Path) -> None:
    experiment = ExperimentProfile(name="step", procedure="voltage_step", motor="ms150_dcm150f",
                                   duration_s=1.0, period_s=0.001, step_V=6.0, step_time_s=0.2)
    with StandBus("ms150_dcm150f", can_config, simulate=True, seed=SEED,
                  heartbeat_period_s=CALM_HEARTBEAT_S) as bus:
        record = StandController(bus).run_experiment(experiment, tmp_path).runs[0]
    run = read_run(record.path, "step")
    before, after = run["voltage_V"][:150], run["voltage_V"][-100:]
    assert np.all(before == 0.0)
    assert np.allclose(after, 6.0, atol=1e-3)  # voltage travels in mV
    assert run["velocity_rad_s"][-1] > 1.0  # the motor turns after the step


def test_limits_are_checked_before_anything_is_sent(tmp_path: Path) -> None:
    experiment = ExperimentProfile(name="hot", procedure="voltage_step", motor="ms150_dcm150f",
                                   duration_s=0.5, period_s=0.001, step_V=12.0,
                                   step_time_s=0.1)  # limit: 10 V
    config = BusConfig("virtual", "test-limits")
    with can.Bus(interface="virtual", channel=config.channel) as spy, \
            StandBus("ms150_dcm150f", config, simulate=True) as bus:
        while spy.recv(0.05) is not None:
            pass  # the simulated drives' boot-up messages
        with pytest.raises(LimitError, match="voltage command reaches 12 V"):
            StandController(bus).run_experiment(experiment, tmp_path)
        assert spy.recv(0.1) is None, "a frame was sent although the limit was exceeded"
        assert bus.sim is not None and bus.sim.nodes[0].syncs == 0
    assert not list(tmp_path.iterdir())


def test_realtime_samples_are_never_misattributed(can_config: BusConfig, tmp_path: Path) -> None:
    """Real time, 15 ms SYNC (slower after a run that kept too few): a sample may be lost
    under load (counted), but every sample kept is the one measured at its own SYNC, as the
    direct simulation proves."""
    stand = load_stand("cycloidal_two_motor")
    kept: list[str] = []
    checked = 0
    for attempt in range(REALTIME_ATTEMPTS):
        period_s = REALTIME_FIRST_PERIOD_S * 2 ** attempt
        experiment = ExperimentProfile(name="rt", procedure="efficiency", stand="cycloidal_two_motor",
                                       duration_s=REALTIME_SAMPLES * period_s, period_s=period_s)
        (procedure, _), = plan(experiment)
        direct = simulate_stand_procedure(procedure, stand, load_motor(stand.motor_in),
                                          load_motor(stand.motor_out), seed=SEED)
        with StandBus("cycloidal_two_motor", can_config, simulate=True, seed=SEED,
                      heartbeat_period_s=CALM_HEARTBEAT_S) as bus:
            record = StandController(bus, "realtime").run_experiment(
                experiment, tmp_path / str(attempt)).runs[0]
            late_targets = bus.master.late_target_windows
        assert record.samples == REALTIME_SAMPLES and record.aborted is None
        # Where the kernel sends the SYNCs, a target the loaded master sent after its SYNC
        # acted a SYNC late: the run says so, and from there on the stand did another
        # experiment.
        assert record.late_targets == len(late_targets)
        assert not late_targets or not record.complete
        first_late = late_targets[0] if late_targets else REALTIME_SAMPLES
        if record.path is None:  # every sample lost, counted: nothing to misattribute
            assert record.lost and max(record.lost.values()) > 0
            kept.append(f"{period_s * 1e3:g} ms: none kept, lost {record.lost}")
            continue
        text = Path(record.path).read_text().splitlines()
        header = text[0].split(",")
        rows = np.array([[float(v) for v in line.split(",")] for line in text[1:]])
        k = np.rint(rows[:, header.index("time_s")] / procedure.sample_period_s).astype(int)
        rows, k = rows[k <= first_late], k[k <= first_late]  # a late target acts after sample k
        # Under load (a one-CPU User-Mode Linux) answers miss their window and are dropped,
        # counted; what must never happen is a kept sample from another SYNC: checked on
        # every run.
        for column in ("position_in_rad", "position_out_rad"):
            error = np.abs(rows[:, header.index(column)] - direct[column][k])
            assert not len(error) or np.max(error) <= 1.01 * ONE_COUNT_RAD, column
        kept.append(f"{period_s * 1e3:g} ms: {len(k)} kept before the first late target "
                    f"{first_late}, lost {record.lost}")
        checked += len(k)
        if checked >= MIN_KEPT or len(k) >= first_late:
            return
    pytest.fail(f"the runs kept too few samples to check: {kept}")
