"""The kinematic load estimate of a backlash (stand.diagnosis.backlash_load.load_estimate): without
restitution it fills stretches of contact at once, and must give what stepping every
sample gives, to the last bit (the diagnosis' verdicts must not move with its speed)."""

from __future__ import annotations

import numpy as np
import pytest

from stand.diagnosis.backlash_load import load_estimate

DT_S = 1e-3


def _motion(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A shaft that reverses often, with dwell and fast stretches (rad, rad/s)."""
    rng = np.random.default_rng(seed)
    accel = np.repeat(rng.standard_normal(400), 25) * 400.0
    omega = np.cumsum(accel) * DT_S
    omega -= np.linspace(omega[0], omega[-1], len(omega))  # end where it started
    theta = np.cumsum(omega) * DT_S
    return theta, np.gradient(theta, DT_S)


def _stepped(theta: np.ndarray, omega: np.ndarray, gap: float) -> tuple[np.ndarray, np.ndarray]:
    """The estimate sample by sample, as the model states it: the load coasts, and is
    carried along from the edge of the gap the motor reaches."""
    tl, wl = float(theta[0]), float(omega[0])
    out_t, out_w = [tl], [wl]
    for th, om in zip(theta[1:].tolist(), omega[1:].tolist(), strict=True):
        tl += wl * DT_S
        if th - tl > gap:
            tl, wl = th - gap, om
        elif th - tl < -gap:
            tl, wl = th + gap, om
        out_t.append(tl)
        out_w.append(wl)
    return np.array(out_t), np.array(out_w)


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("gap", [0.0, 1e-4, 3e-3, 0.05, 1.0])
def test_contact_stretches_filled_at_once_match_the_sample_loop(seed: int, gap: float) -> None:
    theta, omega = _motion(seed)
    fast = load_estimate(theta, omega, gap, DT_S, restitution=0.0)
    stepped = _stepped(theta, omega, gap)
    np.testing.assert_array_equal(fast[0], stepped[0])
    np.testing.assert_array_equal(fast[1], stepped[1])
    carried = np.abs(theta - fast[0]) >= gap * (1 - 1e-12)
    assert carried.mean() > 0.1  # contact and coasting both occur
    assert carried.mean() < 1 or gap == 0.0
