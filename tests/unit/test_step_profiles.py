"""Step identification converges from its own start on small, medium and large motors."""

from __future__ import annotations

import pytest

from stand.profiles import load_motor
from stand.stepid import PARAM_NAMES, identify_steps
from stand.stepid.simulated import simulate_step_run

#: Profile, step voltage (V) and run length (s): about ten mechanical time constants.
MOTORS = [
    ("small_ironcore_19v", 12.0, 0.5),
    ("medium_pmdc_24v", 12.0, 0.5),
    ("ms150_dcm150f", 8.5, 5.0),
]


def true_params(profile: str) -> dict[str, float]:
    m = load_motor(profile).motor
    return dict(zip(PARAM_NAMES, (m.R, m.L, m.Kt, m.J, m.D), strict=True))


@pytest.mark.parametrize("method", ["trf", "lm"])
@pytest.mark.parametrize("profile, volts, seconds", MOTORS)
def test_converges_with_current_on_every_motor_size(profile: str, volts: float, seconds: float,
                                                    method: str) -> None:
    run = simulate_step_run(profile, [volts], seconds, seed=31)
    result = identify_steps([run], method=method)
    truth = true_params(profile)
    assert result.converged, result.message
    assert result.identifiable == list(PARAM_NAMES)
    for name in PARAM_NAMES:
        # Within 3 % or, for a parameter the step barely excites (viscous friction of
        # a small motor), within 4 reported standard errors.
        error = abs(result.params[name] - truth[name])
        assert error < max(0.03 * truth[name], 4 * result.std[name]), name
    # The equation-error start is already close, so no hand-tuned start is involved.
    assert result.start["den"][1] == pytest.approx(result.transfer_function["den"][1], rel=0.2)


def test_the_profiles_are_plausible_and_in_voltage_mode() -> None:
    for profile, volts, _ in MOTORS:
        spec = load_motor(profile)
        assert spec.drive.mode == "voltage"
        assert spec.sensors.velocity_noise_rad_s is not None  # a tacho
        assert volts <= spec.limits.voltage_V
        m = spec.motor
        electrical, mechanical = m.L / m.R, m.R * m.J / m.Kt**2
        assert electrical < mechanical  # the usual order for DC motors
        assert spec.sample_period_s < electrical  # the step shows the electrical pole
