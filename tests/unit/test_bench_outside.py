"""The benchmark's effects outside the vocabulary plant the physics their docstrings state
(tests/bench/diagnose/outside.py): the set written after every rule, UNSEEN."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.bench.diagnose.benchmark import OUTSIDE_SETS, case_class, draw_case
from tests.bench.diagnose.outside import UNSEEN, current_dead_band, dahl_friction, warming_drag

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


def test_an_unseen_case_plants_one_unseen_effect_beside_the_others_cases_unchanged() -> None:
    seed, found = 291, set()
    for index in range(40):
        if case_class(index, seed, outside_share=0.3) != "outside":
            # the other cases are drawn as without the outside share
            assert draw_case(index, seed, outside_share=0.3, outside_set="unseen", min_snr=0) \
                == draw_case(index, seed, min_snr=0)
            continue
        case = draw_case(index, seed, outside_share=0.3, outside_set="unseen", min_snr=0)
        assert case.effects == {} and len(case.outside) == 1
        found |= set(case.outside)
    assert found and found <= set(UNSEEN) and OUTSIDE_SETS["unseen"] is UNSEEN
