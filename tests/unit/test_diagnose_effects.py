"""Each effect of the vocabulary, planted in simulated data, is found by the diagnosis.

The stand: a small motor in current mode (PRBS of ± 0.5 A), a 1000-line encoder,
current noise 0.01 A, 1 ms sampling; TRAIN and HOLDOUT are 6 s each, from different
excitation sequences and noise. Effect sizes are clear but not extreme (a few % to
20 % of the drive torque), so that a failing search or a broken significance test
fails here.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from stand import effects
from stand.diagnosis import diagnose
from stand.excitation import excitation
from stand.physics.effects import Effects
from stand.physics.parts import DriveParams, MotorParams, SensorParams
from stand.physics.plant import MotorPlant
from stand.physics.simulate import simulate_motor
from stand.runfile import Run
from tests.unit.test_ident_effects import KT_OVER_J, sticking_speed_loop_run

MOTOR = MotorParams(R=2.0, L=1e-3, Kt=0.05, J=2e-5, D=5e-5)
SENSORS = SensorParams(encoder_lines=1000, current_noise_A=0.01)
DT_S = 1e-3
DURATION_S = 6.0


def stand_runs(effects: dict[str, dict[str, float]], seed: int = 1,
               hold: tuple[int, int] = (50, 35), kind: str = "prbs",
               dt_s: float = DT_S, motor: MotorParams = MOTOR,
               sensors: SensorParams = SENSORS, amplitude: tuple[float, float] = (0.5, 0.5),
               duration_s: float = DURATION_S,
               extra_torque: Callable[[float, float, float, float], float] | None = None
               ) -> tuple[Run, Run]:
    """TRAIN and HOLDOUT of the test stand with ``effects`` (``kind`` of current command
    of ``amplitude`` A, sampled every ``dt_s``; another ``motor``, ``sensors`` or
    ``duration_s`` if given; ``extra_torque``: a torque outside the vocabulary, N·m,
    of θ, ω, i, t)."""
    runs = []
    for k in range(2):
        plant = MotorPlant(motor, DriveParams(mode="current"), sensors,
                           Effects.from_mapping(effects), seed=seed + k)
        plant.extra_torque = extra_torque
        samples = int(round(duration_s / dt_s))
        command = excitation(kind, samples, dt_s, 0.0, amplitude[k], hold[k], seed=seed + k)
        runs.append(simulate_motor(plant, "current", command, dt_s))
    return runs[0], runs[1]


PLANTED: dict[str, dict[str, Any]] = {
    "coulomb_friction": {"Tc": 0.004},
    "stribeck_friction": {"Tc": 0.002, "Ts": 0.008, "ws": 5.0},
    "cogging": {"Tcog": 0.003, "N": 12, "phi": 0.5},
    "current_offset": {"i0": 0.05},
    "delay": {"k": 3},
    "backlash": {"gap": 0.02, "J_load": 2e-5},
    "torque_ripple": {"eps": 0.15, "N": 8, "phi": 0.3},
}


#: Backlash: the candidate's rigid contact (with a coefficient of restitution) only
#: approximates the simulator's 150 Hz contact spring, and its coefficients come from the
#: equation error on the kinematic load estimate, which biases them: here the candidate
#: shrinks the gap by 0.29, the model with the true gap and load and the equation
#: error's coefficients by 0.30, and with every parameter true by 0.39.
MIN_SHRINK = {"backlash": 0.25}


@pytest.mark.parametrize("effect", list(PLANTED))
def test_planted_effect_is_the_verdict(effect: str) -> None:
    train, holdout = stand_runs({effect: PLANTED[effect]})
    result = diagnose(train, holdout, kt=MOTOR.Kt)
    assert result.verdict.split("+")[0] == effect, result.message
    score = next(e for e in result.effects if e.effect == effect)
    assert score.significant
    assert set(score.params) <= set(effects.get(effect).units), score.params
    # The effect explains much of the gap (the rest is sensor noise and quantization).
    assert score.shrink > MIN_SHRINK.get(effect, 0.4), score


def test_no_effect_gives_none() -> None:
    train, holdout = stand_runs({})
    result = diagnose(train, holdout)
    assert result.verdict == "none", result.message
    assert not any(e.significant for e in result.effects)
    assert result.verdict_gap_percent == result.gap_percent


def test_fitted_parameters_are_physical() -> None:
    """Coulomb level, offset, delay and orders come back in physical units."""
    tc = PLANTED["coulomb_friction"]["Tc"]
    result = diagnose(*stand_runs({"coulomb_friction": {"Tc": tc}}), kt=MOTOR.Kt)
    params = next(e for e in result.effects if e.effect == "coulomb_friction").params
    # 15 %: friction near standstill (sticking) is only partly seen by sign(ω).
    np.testing.assert_allclose(params["Tc"], tc, rtol=0.15)
    np.testing.assert_allclose(params["Tc_over_Kt_A"], tc / MOTOR.Kt, rtol=0.15)
    result = diagnose(*stand_runs({"current_offset": {"i0": 0.05}}))
    params = next(e for e in result.effects if e.effect == "current_offset").params
    np.testing.assert_allclose(params["i0"], 0.05, rtol=0.1)  # 10 %: noise over 6 s
    result = diagnose(*stand_runs({"cogging": PLANTED["cogging"]}), kt=MOTOR.Kt)
    params = next(e for e in result.effects if e.effect == "cogging").params
    assert params["N"] == 12
    np.testing.assert_allclose(params["Tcog"], 0.003, rtol=0.1)
    assert abs(np.angle(np.exp(1j * (params["phi"] - 0.5)))) < 0.3  # rad


@pytest.mark.parametrize(("effect", "planted", "size"), [
    ("cogging", {"Tcog": 0.003, "N": 30, "phi": 0.5}, "Tcog"),
    ("torque_ripple", {"eps": 0.1, "N": 24, "phi": 1.0}, "eps"),
])
def test_high_orders_come_back_at_full_size(effect: str, planted: dict[str, float],
                                            size: str) -> None:
    """At the stand's speed (~120 rad/s RMS) these orders turn through 3-4 rad per
    sample: their values at the samples are aliased, and only their mean over each
    period (model.periodic_mean) gives their size (sampled values gave 25-30 % less)."""
    result = diagnose(*stand_runs({effect: planted}), kt=MOTOR.Kt)
    assert result.verdict == effect, result.message
    params = next(e for e in result.effects if e.effect == effect).params
    assert params["N"] == planted["N"]
    np.testing.assert_allclose(params[size], planted[size], rtol=0.1)
    assert abs(np.angle(np.exp(1j * (params["phi"] - planted["phi"])))) < 0.2  # rad


def test_backlash_comes_back_as_gap_and_load_inertia() -> None:
    planted = PLANTED["backlash"]
    result = diagnose(*stand_runs({"backlash": planted}), kt=MOTOR.Kt)
    params = next(e for e in result.effects if e.effect == "backlash").params
    # 25 %: the gap is refined between the grid's points (1.5x apart here) to an eighth of
    # a step by simulating TRAIN with the equation error's coefficients (biased, see
    # MIN_SHRINK): 0.0245 rad here; 30 % on the load: the contact is a 150 Hz spring
    np.testing.assert_allclose(params["gap"], planted["gap"], rtol=0.25)
    np.testing.assert_allclose(params["J_load"], planted["J_load"], rtol=0.3)
    assert params["restitution"] in (0.0, 0.5)


def test_a_ripple_turning_fast_within_a_sample_is_named_with_its_order() -> None:
    # A speed-loop stand sampled every 2.04 ms at up to 140 rad/s: a ripple of order 7
    # turns 2 rad a sample there, and the equation error ranks order 6 first. Simulating
    # TRAIN picks 7 among the orders of smallest equation error, and HOLDOUT confirms it
    # (before: order 6, which simulated HOLDOUT worse than no ripple at all, and the
    # verdict `unexplained`). On seeds 1-5 and 7 of this stand the order comes back on 3
    # of 6 (before: none); on the others TRAIN's simulation prefers order 6 too.
    motor = MotorParams(R=0.597, L=6.32e-4, Kt=0.0688, J=5.21e-5, D=3.34e-4)
    drive = DriveParams(mode="speed", supply_V=48.0, current_limit_A=49.0,
                        speed_kp=0.0991, speed_ki=2.595)
    sensors = SensorParams(encoder_lines=5000, current_noise_A=0.0192)
    ripple = {"torque_ripple": {"eps": 0.17, "N": 7, "phi": 0.16}}
    dt = 2.04e-3
    runs = []
    for k, (hold, amplitude) in enumerate(((25, 123.0), (32, 105.0))):
        plant = MotorPlant(motor, drive, sensors, Effects.from_mapping(ripple), seed=1 + k)
        command = excitation("prbs", int(10.0 / dt), dt, 0.0, amplitude, hold, seed=1 + k)
        run = simulate_motor(plant, "speed", command, dt)
        runs.append(Run({c: run[c] for c in ("time_s", "current_A", "position_rad",
                                             "speed_target_rad_s")}, f"run{k}"))
    result = diagnose(runs[0], runs[1])
    assert result.verdict == "torque_ripple"
    assert result.verdict_params["torque_ripple"]["N"] == 7


def test_a_speed_loop_that_sticks_at_each_reversal_is_diagnosed_as_coulomb_friction() -> None:
    # A 3 Hz speed loop reversing between ±10 rad/s against Coulomb friction of 0.16 A
    # (Tc/Kt), which its 0.075 A kick cannot break away: the shaft rests a third of the
    # run while the integrator winds the current up. Fitted there, the equation error
    # put Kt/J at 4 % of the truth, and nothing explained the 27 % gap (`unexplained`).
    # With the rows at rest left out of every fit (the simulation steps the sticking
    # itself), Coulomb friction is named at its size and the model's Kt/J is within 5 %.
    train, holdout = sticking_speed_loop_run(2), sticking_speed_loop_run(4)
    result = diagnose(train, holdout)
    assert result.verdict.split("+")[0] == "coulomb_friction", result.message
    assert result.verdict_gap_percent < 0.25 * result.gap_percent
    assert abs(result.verdict_params["coulomb_friction"]["Tc_over_Kt_A"] / 0.16 - 1) < 0.05
    assert abs(result.model["Kt_over_J"] / KT_OVER_J - 1) < 0.05
