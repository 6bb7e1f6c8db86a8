"""The benchmark's effects outside the vocabulary plant the physics their docstrings state
(tests/bench/diagnose/outside.py): the sets written after every rule, UNSEEN,
UNSEEN_2 to UNSEEN_9. No diagnosis runs here: the last eight are only ever run to be
reported."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.bench.diagnose.benchmark import OUTSIDE_SETS, case_class, draw_case
from tests.bench.diagnose.outside import (
    UNSEEN,
    UNSEEN_2,
    UNSEEN_3,
    UNSEEN_4,
    UNSEEN_5,
    UNSEEN_6,
    UNSEEN_7,
    UNSEEN_8,
    UNSEEN_9,
    ball_detent,
    breathing_rub,
    brush_timing,
    cable_windup,
    current_clipping,
    current_dead_band,
    dahl_friction,
    dragging_brake,
    draw_outside,
    field_weakening,
    fluid_coupling,
    frame_vibration,
    freewheel_flywheel,
    friction_ageing,
    friction_run_in,
    mesh_ripple,
    offset_drift,
    one_way_drag,
    power_law_drag,
    regen_clipping,
    relief_pump,
    rubbing_arc,
    sense_asymmetry,
    shaft_rub,
    slip_clutch,
    turbulent_load,
    voltage_ceiling,
    warming_drag,
    winding_heating,
)

#: Sub-step of the runs below, s (the simulator's is 0.1 ms at 1 kHz).
H = 1e-4


def _sweep(torque, speed: float, seconds: float, t0: float, theta0: float
           ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Angle travelled and torque at each sub-step of a constant ``speed``."""
    n = int(round(seconds / H))
    travel, out = np.empty(n), np.empty(n)
    t, theta = t0, theta0
    for k in range(n):
        t += H
        theta += speed * H
        travel[k] = abs(theta - theta0)
        out[k] = torque(theta, speed, 0.0, t)
    return travel, out, t, theta


def test_dahl_friction_slides_at_its_level_and_builds_up_over_the_presliding_angle() -> None:
    Tc, phi = 0.02, 0.01
    torque = dahl_friction({"Tc": Tc, "phi": phi}, 10.0)
    _, forward, t, theta = _sweep(torque, 2.0, 0.1, 0.0, 0.0)  # 0.2 rad = 20 φ
    assert forward[-1] == pytest.approx(Tc, rel=1e-6)
    travel, back, _, _ = _sweep(torque, -2.0, 0.05, t, theta)
    # after a reversal from steady sliding: Tc·(2·exp(−x/φ) − 1) at x rad travelled back,
    # exact for a constant speed whatever the step
    assert back == pytest.approx(Tc * (2 * np.exp(-travel / phi) - 1), abs=1e-9)
    assert back[np.searchsorted(travel, phi * math.log(2))] == pytest.approx(0.0, abs=0.01 * Tc)


def test_dahl_friction_starts_each_run_at_rest() -> None:
    torque = dahl_friction({"Tc": 0.02, "phi": 0.01}, 10.0)
    _sweep(torque, 2.0, 0.1, 0.0, 0.0)
    # a new run: time starts again, the bristles relaxed, the first sub-step barely loads
    assert abs(torque(0.0, 2.0, 0.0, H)) < 0.01 * 0.02


def test_the_current_dead_band_loses_the_current_up_to_its_edge_by_the_currents_sign() -> None:
    torque = current_dead_band({"Kt": 0.1, "delta": 0.5}, 10.0)
    assert [torque(0.0, 5.0, i, 0.0) for i in (-2.0, -0.2, 0.0, 0.3, 2.0)] == pytest.approx(
        [-0.05, -0.02, 0.0, 0.03, 0.05])
    # the sign of the current, not of the speed, as a friction's would be
    assert torque(0.0, -5.0, 2.0, 0.0) == pytest.approx(0.05)


def test_warming_drag_falls_over_each_run() -> None:
    torque = warming_drag({"c": 1e-4, "beta": 0.5}, 10.0)
    assert [torque(0.0, 100.0, 0.0, t) for t in (0.0, 5.0, 10.0 + 2.5)] == pytest.approx(
        [0.01, 0.0075, 0.00875])


def test_field_weakening_takes_a_share_of_the_torque_growing_with_the_speed_up_to_twice() -> None:
    torque = field_weakening({"Kt": 0.1, "gamma": 0.2, "omega_ref": 100.0}, 10.0)
    assert [torque(0.0, w, 2.0, 0.0) for w in (0.0, -50.0, 100.0, 400.0)] == pytest.approx(
        [0.0, 0.02, 0.04, 0.08])


def test_the_brake_drags_until_its_release_in_every_run() -> None:
    torque = dragging_brake({"T": 0.01, "t_release": 3.0, "eps": 0.1}, 10.0)
    assert [torque(0.0, w, 0.0, t) for w, t in ((5.0, 1.0), (-5.0, 2.9), (5.0, 3.1),
                                                 (5.0, 11.0))] == pytest.approx(
        [0.01, -0.01, 0.0, 0.01], abs=1e-12)


def test_the_rub_acts_over_its_arc_of_each_load_revolution() -> None:
    r, arc = 4.0, 1.0
    torque = rubbing_arc({"T": 0.01, "ratio": r, "phi": 0.0, "arc": arc, "eps": 0.1}, 10.0)
    theta = np.linspace(0.0, 2 * math.pi * r, 100001)
    rubbed = np.array([torque(x, 5.0, 0.0, 0.0) for x in theta]) > 0
    assert np.mean(rubbed) == pytest.approx(arc / (2 * math.pi), abs=1e-3)
    assert rubbed[0] and not rubbed[len(theta) // 2]


def test_the_winding_warms_towards_its_currents_steady_rise_and_starts_each_run_cold() -> None:
    kt, kappa, iref, tau = 0.1, 0.2, 2.0, 1.0
    torque = winding_heating({"Kt": kt, "kappa": kappa, "i_ref": iref, "tau": tau}, 10.0)
    t = 0.0
    for _ in range(int(round(0.5 / H))):  # 0.5 s at 2.5 A: the rise heads for 1.5625
        t += H
        loss = torque(0.0, 5.0, 2.5, t)
    rise = 1.5625 * (1 - math.exp(-(t - H) / tau))  # from the first call on
    assert loss == pytest.approx(kt * kappa * rise * 2.5, rel=1e-6)
    # at no current it cools with τ, and carries no loss
    for _ in range(int(round(1.0 / H))):
        t += H
        assert torque(0.0, 5.0, 0.0, t) == 0.0
    assert torque(0.0, 5.0, 1e-9, t + H) == pytest.approx(
        kt * kappa * rise * math.exp(-(1.0 + H) / tau) * 1e-9, rel=1e-4)
    # a new run: time starts again, the winding cold
    assert torque(0.0, 5.0, 4.0, H) == pytest.approx(0.0, abs=1e-12)
    # beyond twice the rise of i_ref the loss is held there
    for _ in range(int(round(3.0 / H))):  # 3 s at 4 A: the rise heads for (4/2)² = 4
        t += H
        loss = torque(0.0, 5.0, 4.0, t)
    assert loss == pytest.approx(kt * kappa * 2.0 * 4.0, rel=1e-9)


def test_the_asymmetric_sensor_loses_a_share_of_the_positive_current_only() -> None:
    torque = sense_asymmetry({"Kt": 0.1, "eps": 0.25}, 10.0)
    assert [torque(0.0, w, i, 0.0) for w, i in ((5.0, 2.0), (-5.0, 2.0), (5.0, -2.0))] \
        == pytest.approx([0.1 * 2.0 * 0.2, 0.1 * 2.0 * 0.2, 0.0])


def test_the_cable_tightens_with_the_net_travel_from_where_each_run_started() -> None:
    torque = cable_windup({"T": 0.01, "theta_s": 10.0}, 10.0)
    assert torque(100.0, 5.0, 0.0, 0.0) == 0.0  # the run starts at 100 rad, slack
    assert torque(110.0, 5.0, 0.0, 1.0) == pytest.approx(0.01 * math.tanh(1.0))
    assert torque(90.0, 5.0, 0.0, 2.0) == pytest.approx(-0.01 * math.tanh(1.0))
    # the travel counts, not the time: back at the start it is slack again
    assert torque(100.0, -5.0, 0.0, 3.0) == 0.0
    # a new run starts slack wherever the shaft is
    assert torque(200.0, 5.0, 0.0, 0.5) == 0.0


def test_the_power_law_drag_grows_between_a_dry_and_a_viscous_one() -> None:
    torque = power_law_drag({"T": 0.01, "omega_ref": 100.0, "delta": 0.5, "eps": 1e-6}, 10.0)
    assert [torque(0.0, w, 0.0, 0.0) for w in (25.0, 100.0, -400.0)] == pytest.approx(
        [0.005, 0.01, -0.02])


def test_the_bent_shaft_rubs_once_a_motor_revolution_against_the_motion() -> None:
    torque = shaft_rub({"Tc": 0.01, "phi": 0.0, "eps": 1e-6}, 10.0)
    angles = (math.pi / 2, 3 * math.pi / 2, 2 * math.pi + math.pi / 2)
    assert [torque(x, 5.0, 0.0, 0.0) for x in angles] == pytest.approx([0.01, 0.0, 0.01])
    assert torque(0.0, -5.0, 0.0, 0.0) == pytest.approx(-0.005)


def test_the_mesh_ripple_repeats_at_its_order_whatever_the_speed() -> None:
    order = 17 / 4.3
    torque = mesh_ripple({"T": 0.01, "order": order, "phi": 0.3}, 10.0)
    assert torque(0.0, 5.0, 0.0, 0.0) == pytest.approx(0.01 * math.sin(0.3))
    assert torque(2 * math.pi / order, -5.0, 1.0, 3.0) == pytest.approx(0.01 * math.sin(0.3))


def test_a_drawn_mesh_ripple_is_no_whole_order() -> None:
    rng = np.random.default_rng(1)
    orders = [draw_outside("mesh_ripple", rng, 0.05, 0.01, 0.2, 100.0, 0.1,
                           duration_s=10.0)["order"] for _ in range(200)]
    assert min(abs(q - round(q)) for q in orders) >= 0.2
    assert min(orders) >= 11 / 7.8 and max(orders) <= 31 / 2.2


def test_the_offset_drift_grows_over_each_run() -> None:
    torque = offset_drift({"Kt": 0.1, "i0": -0.5}, 10.0)
    assert [torque(0.0, 5.0, 1.0, t) for t in (0.0, 5.0, 12.5)] == pytest.approx(
        [0.0, -0.025, -0.0125])


def test_the_fluid_coupling_drags_like_a_damper_then_hands_over_its_flywheel() -> None:
    J_l, tau = 2e-4, 0.05
    torque = fluid_coupling({"J_load": J_l, "tau": tau}, 10.0)
    # a run starting at 10 rad/s: the flywheel with the motor, no torque
    assert torque(0.0, 10.0, 0.0, 0.0) == pytest.approx(0.0)
    # a speed step to 20 rad/s: at first a damper c = J_l/τ on the 10 rad/s slip, which
    # decays as exp(−t/τ), exact whatever the step; the flywheel took J_l·10 rad/s
    _, out, t, _ = _sweep(torque, 20.0, 0.3, 0.0, 0.0)
    times = H * np.arange(len(out))
    assert out == pytest.approx(J_l / tau * 10.0 * np.exp(-times / tau), rel=1e-9, abs=1e-15)
    assert float(np.sum(out) * H) == pytest.approx(J_l * 10.0, rel=2e-3)
    # a new run (the time starts again): the flywheel with the motor again
    assert torque(0.0, -3.0, 0.0, 0.0) == pytest.approx(0.0)


def test_the_turbulent_load_is_random_of_its_rms_and_correlation_time_and_drawn_again_alike(
        ) -> None:
    sigma, tau = 0.01, 0.02
    params = {"sigma": sigma, "tau": tau, "seed": 7.0}
    torque = turbulent_load(params, 100.0)
    _, out, _, _ = _sweep(torque, 5.0, 40.0, 0.0, 0.0)
    assert float(np.std(out)) == pytest.approx(sigma, rel=0.1)
    lag = int(round(tau / H))  # an OU process correlates as exp(−lag/τ)
    corr = float(np.corrcoef(out[:-lag], out[lag:])[0, 1])
    assert corr == pytest.approx(math.exp(-1.0), abs=0.08)
    again = turbulent_load(params, 100.0)
    assert [again(0.0, 5.0, 0.0, H * (k + 1)) for k in range(50)] == pytest.approx(out[:50])
    other = turbulent_load({**params, "seed": 8.0}, 100.0)
    assert [other(0.0, 5.0, 0.0, H * (k + 1)) for k in range(50)] != pytest.approx(out[:50])


def test_the_one_way_drag_is_viscous_in_one_direction_only() -> None:
    torque = one_way_drag({"c": 1e-3, "s": -1.0}, 10.0)
    assert [torque(0.0, w, 0.0, 0.0) for w in (-20.0, -5.0, 5.0, 20.0)] == pytest.approx(
        [-0.02, -0.005, 0.0, 0.0])
    forward = one_way_drag({"c": 1e-3, "s": 1.0}, 10.0)
    assert [forward(0.0, w, 0.0, 0.0) for w in (-5.0, 5.0)] == pytest.approx([0.0, 0.005])


def test_the_ball_detent_pulls_into_its_notch_once_a_load_revolution() -> None:
    r, w = 4.0, 0.1
    torque = ball_detent({"T": 0.01, "ratio": r, "phi": 0.0, "width": w}, 10.0)
    # the load one half-width past the notch: the peak, pulling back (opposing)
    assert torque(r * w, 5.0, 0.0, 0.0) == pytest.approx(0.01)
    assert torque(-r * w, -5.0, 0.0, 0.0) == pytest.approx(-0.01)
    # the same one load revolution (r motor revolutions) on, whatever the speed
    assert torque(r * (w + 2 * math.pi), -5.0, 1.0, 3.0) == pytest.approx(0.01)
    # at the notch's bottom and half a load revolution away: nothing
    assert [torque(x, 5.0, 0.0, 0.0) for x in (0.0, r * math.pi * 0.999)] == pytest.approx(
        [0.0, 0.0], abs=1e-12)


def test_the_slip_clutch_carries_a_gentle_acceleration_and_slips_at_its_limit() -> None:
    J_l, slip = 1e-3, 0.01
    torque = slip_clutch({"J_load": J_l, "T_slip": slip}, 10.0)
    torque(0.0, 0.0, 0.0, 0.0)  # a new run at rest
    # a ramp of the shaft at 2 rad/s²: the flywheel follows, carrying J_l·2 = 0.002 N·m
    t, out = 0.0, []
    for _ in range(2000):
        t += H
        out.append(torque(0.0, 2.0 * t, 0.0, t))
    # (the torque read before each sub-step's update lags it by half a sub-step: h/2τ)
    assert out[-1] == pytest.approx(J_l * 2.0 * (1 + H / 0.004), rel=1e-3)
    # a jump of the shaft's speed: the clutch slips at its limit, and the flywheel takes
    # T_slip/J_l = 10 rad/s² meanwhile
    jumped = [torque(0.0, 50.0, 0.0, t + H * (k + 1)) for k in range(1000)]
    assert jumped[0] == pytest.approx(slip) and jumped[-1] == pytest.approx(slip)
    # the other way round it slips the other way
    assert torque(0.0, -50.0, 0.0, t + 0.2) == pytest.approx(-slip)


def test_the_friction_runs_in_with_the_travel_not_the_time() -> None:
    Tc, a, s0 = 0.01, 0.5, 10.0
    torque = friction_run_in({"Tc": Tc, "a": a, "s0": s0, "eps": 1e-6}, 10.0)
    assert torque(0.0, 5.0, 0.0, 0.0) == pytest.approx(Tc)
    # 5 rad there and 5 back (the travel counts both ways): Tc·(1 − a·(1 − e^−1))
    _, _, t, theta = _sweep(torque, 5.0, 1.0, 0.0, 0.0)
    _, back, t, theta = _sweep(torque, -5.0, 1.0, t, theta)
    level = 1 - a * (1 - math.exp(-1.0))
    assert back[-1] == pytest.approx(-Tc * level, rel=1e-3)
    # five seconds at a standstill run nothing in: the same level when it moves again
    assert torque(theta, 5.0, 0.0, t + 5.0) == pytest.approx(Tc * level, rel=1e-3)


def test_the_current_clipping_loses_only_beyond_the_limit() -> None:
    torque = current_clipping({"Kt": 0.1, "I_lim": 2.0}, 10.0)
    assert [torque(0.0, 5.0, i, 0.0) for i in (-3.0, -1.0, 0.0, 1.9, 2.5)] == pytest.approx(
        [-0.1, 0.0, 0.0, 0.0, 0.05])


def test_the_freewheel_drives_its_flywheel_one_way_and_lets_it_overrun() -> None:
    J_l, tau_l = 1e-3, 0.5
    torque = freewheel_flywheel({"J_load": J_l, "s": 1.0, "tau_load": tau_l}, 10.0)
    torque(0.0, 0.0, 0.0, 0.0)  # a new run: the flywheel at rest
    # the shaft turning backwards: the freewheel overruns, no torque
    assert torque(0.0, -20.0, 0.0, H) == 0.0
    # a ramp forwards at 2 rad/s²: engaged, it carries J_l·2 and the flywheel's own drag
    t = H
    for _ in range(20000):
        t += H
        carried = torque(0.0, 2.0 * (t - H), 0.0, t)
    assert carried == pytest.approx(J_l * (2.0 + 2.0 * (t - H) / tau_l), rel=0.02)
    # the shaft stops at once: the flywheel overruns and coasts, nothing carried
    assert [torque(0.0, 0.0, 0.0, t + H * k) for k in range(1, 5)] == [0.0] * 4


def test_the_breathing_rub_swells_and_fades_in_time_whatever_the_position() -> None:
    torque = breathing_rub({"Tc": 0.01, "f_hz": 0.25, "phi": 0.0, "eps": 1e-6}, 10.0)
    assert [torque(0.0, 5.0, 0.0, t) for t in (0.0, 1.0, 3.0)] == pytest.approx(
        [0.005, 0.01, 0.0], abs=1e-12)
    assert torque(123.0, -5.0, 0.0, 1.0) == pytest.approx(-0.01)


def test_the_frame_vibration_shakes_at_its_frequency_whatever_the_shaft_does() -> None:
    torque = frame_vibration({"T": 0.01, "f_hz": 50.0, "phi": 0.0}, 10.0)
    assert [torque(0.0, 5.0, 1.0, t) for t in (0.0, 0.005, 0.015)] == pytest.approx(
        [0.0, 0.01, -0.01], abs=1e-12)
    assert torque(123.0, -7.0, -3.0, 0.005) == pytest.approx(0.01)


def test_the_regen_clipping_loses_beyond_the_limit_only_while_braking() -> None:
    torque = regen_clipping({"Kt": 0.1, "I_lim": 2.0}, 10.0)
    # driving, whatever the current: nothing lost
    assert [torque(0.0, w, i, 0.0) for w, i in ((5.0, 3.0), (-5.0, -3.0), (5.0, 1.0))] \
        == [0.0, 0.0, 0.0]
    # braking: within the limit nothing, beyond it the excess
    assert torque(0.0, 5.0, -1.5, 0.0) == 0.0
    assert torque(0.0, 5.0, -3.0, 0.0) == pytest.approx(-0.1)
    assert torque(0.0, -5.0, 3.5, 0.0) == pytest.approx(0.15)


def test_the_brush_timing_changes_the_torque_constant_with_the_direction_of_rotation() -> None:
    torque = brush_timing({"Kt": 0.1, "eps": 0.2, "s": 1.0, "eps_w": 1e-6}, 10.0)
    # the motor delivers Kt·i·(1 ± ε): the loss is −Kt·ε·i one way, +Kt·ε·i the other
    assert torque(0.0, 5.0, 2.0, 0.0) == pytest.approx(-0.04)
    assert torque(0.0, -5.0, 2.0, 0.0) == pytest.approx(0.04)
    assert torque(0.0, -5.0, -2.0, 0.0) == pytest.approx(-0.04)
    assert torque(0.0, 5.0, 0.0, 0.0) == 0.0
    other = brush_timing({"Kt": 0.1, "eps": 0.2, "s": -1.0, "eps_w": 1e-6}, 10.0)
    assert other(0.0, 5.0, 2.0, 0.0) == pytest.approx(0.04)


def test_the_voltage_ceiling_limits_the_driving_current_less_the_faster_the_shaft() -> None:
    torque = voltage_ceiling({"Kt": 0.1, "I0": 4.0, "omega_0": 100.0}, 10.0)
    # driving at 50 rad/s the bridge gives at most 2 A: beyond it the excess is lost
    assert torque(0.0, 50.0, 1.5, 0.0) == 0.0
    assert torque(0.0, 50.0, 3.0, 0.0) == pytest.approx(0.1)
    assert torque(0.0, -50.0, -3.0, 0.0) == pytest.approx(-0.1)
    # at 75 rad/s at most 1 A, at the no-load speed and beyond nothing
    assert torque(0.0, 75.0, 3.0, 0.0) == pytest.approx(0.2)
    assert torque(0.0, 120.0, 3.0, 0.0) == pytest.approx(0.3)
    # braking, whatever the current: nothing lost
    assert torque(0.0, 75.0, -3.0, 0.0) == 0.0 and torque(0.0, -75.0, 3.0, 0.0) == 0.0


def test_the_relief_pump_is_viscous_below_its_knee_and_level_above() -> None:
    torque = relief_pump({"T_max": 0.02, "omega_k": 40.0}, 10.0)
    assert [torque(0.0, w, 0.0, 0.0) for w in (10.0, 20.0, 40.0, 80.0, 400.0)] \
        == pytest.approx([0.005, 0.01, 0.02, 0.02, 0.02])
    assert torque(0.0, -20.0, 0.0, 0.0) == pytest.approx(-0.01)
    assert torque(0.0, 0.0, 0.0, 0.0) == 0.0


def test_the_aged_friction_grows_with_the_rest_and_wears_off_with_the_travel() -> None:
    p = {"dT": 0.02, "tau_d": 0.05, "s0": 0.1, "eps": 1e-3}

    def breakaway(rest_s: float, travel_rad: float) -> float:
        torque = friction_ageing(p, 10.0)
        steps = int(round(rest_s / H))
        for k in range(steps + 1):  # at rest
            torque(0.0, 0.0, 0.0, k * H)
        # moves on at 10 rad/s: the first sub-step after travelling travel_rad
        t = steps * H + H
        return torque(travel_rad, 10.0, 0.0, t)

    # the excess grows with the rest: 1 - exp(-d/tau_d)
    assert breakaway(0.05, 0.0) == pytest.approx(0.02 * (1 - math.exp(-1)), rel=1e-3)
    assert breakaway(0.2, 0.0) == pytest.approx(0.02 * (1 - math.exp(-4)), rel=1e-3)
    assert breakaway(0.005, 0.0) < 0.1 * breakaway(0.2, 0.0)
    # and wears off with the travel since it moved: exp(-s/s0)
    assert breakaway(0.2, 0.1) == pytest.approx(breakaway(0.2, 0.0) * math.exp(-1), rel=1e-6)
    # a new run starts from a fresh rest
    torque = friction_ageing(p, 10.0)
    for k in range(2000):
        torque(0.0, 0.0, 0.0, k * H)
    assert torque(0.0, 10.0, 0.0, 0.0) == 0.0


@pytest.mark.parametrize("name", ["unseen", "unseen_2", "unseen_3", "unseen_4", "unseen_5",
                                  "unseen_6", "unseen_7", "unseen_8", "unseen_9"])
def test_an_unseen_case_plants_one_unseen_effect_beside_the_others_cases_unchanged(
        name: str) -> None:
    seed, found = 291, set()
    for index in range(40):
        if case_class(index, seed, outside_share=0.3) != "outside":
            # the other cases are drawn as without the outside share
            assert draw_case(index, seed, outside_share=0.3, outside_set=name, min_snr=0) \
                == draw_case(index, seed, min_snr=0)
            continue
        case = draw_case(index, seed, outside_share=0.3, outside_set=name, min_snr=0)
        assert case.effects == {} and len(case.outside) == 1
        found |= set(case.outside)
    assert found and found <= set(OUTSIDE_SETS[name])
    assert OUTSIDE_SETS["unseen"] is UNSEEN and OUTSIDE_SETS["unseen_2"] is UNSEEN_2
    assert OUTSIDE_SETS["unseen_3"] is UNSEEN_3 and OUTSIDE_SETS["unseen_4"] is UNSEEN_4
    assert OUTSIDE_SETS["unseen_5"] is UNSEEN_5 and OUTSIDE_SETS["unseen_6"] is UNSEEN_6
    assert OUTSIDE_SETS["unseen_7"] is UNSEEN_7 and OUTSIDE_SETS["unseen_8"] is UNSEEN_8
    assert OUTSIDE_SETS["unseen_9"] is UNSEEN_9
