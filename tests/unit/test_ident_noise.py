"""The current-noise level that passes the identification kernel (stand.ident.noise)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter, sosfiltfilt

from stand.ident.noise import noise_sigma, passband_noise

DT_S = 1e-3
#: Cutoff of a 1 s kernel (half width 1000 samples at 1 kHz), Hz.
CUTOFF_HZ = 0.5


def steps(n: int) -> np.ndarray:
    """Two torque levels, as in a torque-step run: 0.3 A, then 0.5 A from the middle."""
    return np.where(np.arange(n) < n // 2, 0.3, 0.5)


@pytest.mark.parametrize("seed", range(5))
def test_white_noise_level_is_its_variance_within_its_uncertainty(seed: int) -> None:
    # The reported relative uncertainty is a standard error: the level must be within
    # three of them of the true 0.25 A².
    rng = np.random.default_rng(seed)
    x = steps(20_000) + 0.5 * rng.standard_normal(20_000)
    variance, uncertainty = passband_noise(x, DT_S, CUTOFF_HZ)
    assert 0.0 < uncertainty < 0.25
    assert abs(variance / 0.25 - 1.0) < 3 * uncertainty


def test_noise_coloured_towards_high_frequencies_is_read_below_the_passband_level() -> None:
    # White noise of 0.2 A plus 0.6 A above 200 Hz: the differences see mostly the high
    # band, the spectrum near the kernel's passband only the white part (0.04 A²).
    rng = np.random.default_rng(2)
    n = 20_000
    high = sosfiltfilt(butter(4, 200.0, "highpass", fs=1 / DT_S, output="sos"),
                       rng.standard_normal(n))
    x = steps(n) + 0.2 * rng.standard_normal(n) + 0.6 * high / np.std(high)
    variance, uncertainty = passband_noise(x, DT_S, CUTOFF_HZ)
    assert abs(variance / 0.04 - 1.0) < 3 * uncertainty
    assert noise_sigma(x) ** 2 > 3 * variance
