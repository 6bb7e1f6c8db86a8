"""The diagnosis' own signal processing against SciPy's reference implementations: the
zero-phase low-pass (``filtfilt``) and the power spectral density (``welch``), which the
diagnosis reimplements to stay clear of ``scipy.signal``'s import time."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy import signal as sps

from stand.diagnosis.signals import (
    FILTER_FRACTION_OF_NYQUIST,
    FILTER_ORDER,
    PAD_SAMPLES,
    lowpass,
    power_spectral_density,
)

#: Relative to the signal's scale: rounding of a few dozen operations per sample.
ROUNDING = 1e-13


@pytest.mark.parametrize("samples", [3, 40, 61, 62, 500, 20_000])
def test_lowpass_is_scipys_filtfilt(samples: int) -> None:
    b, a = sps.butter(FILTER_ORDER, FILTER_FRACTION_OF_NYQUIST)
    values = np.cumsum(np.random.default_rng(samples).standard_normal((samples, 3)), axis=0)
    expected = sps.filtfilt(b, a, values, axis=0, padtype="odd",
                            padlen=min(PAD_SAMPLES, samples - 1))
    scale = np.max(np.abs(values))
    np.testing.assert_allclose(lowpass(values, axis=0), expected, rtol=0, atol=ROUNDING * scale)
    np.testing.assert_allclose(lowpass(values.T.copy(), axis=1), expected.T, rtol=0,
                               atol=ROUNDING * scale)
    np.testing.assert_allclose(lowpass(values[:, 0]), expected[:, 0], rtol=0,
                               atol=ROUNDING * scale)


@pytest.mark.parametrize(("samples", "segment"), [(20_000, 1024), (1024, 1024), (999, 999),
                                                  (3001, 1000), (1500, 777)])
def test_power_spectral_density_is_scipys_welch(samples: int, segment: int) -> None:
    values = np.cumsum(np.random.default_rng(segment).standard_normal(samples))
    freq, power = sps.welch(values, fs=500.0, nperseg=segment)
    mine_freq, mine = power_spectral_density(values, 1 / 500.0, segment)
    np.testing.assert_allclose(mine_freq, freq, rtol=1e-15)
    np.testing.assert_allclose(mine, power, rtol=0, atol=ROUNDING * np.max(power))


def test_a_diagnosis_does_not_import_scipy_signal_or_stats() -> None:
    """Their imports cost more CPU time than a diagnosis of 20 s at 1 kHz saves elsewhere."""
    code = ("import sys; from stand.cli import main; import stand.cli.diagnose; "
            "import stand.diagnosis.engine; "
            "print(sorted(m for m in sys.modules if m in ('scipy.signal', 'scipy.stats')))")
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            check=True).stdout.strip()
    assert loaded == "[]", loaded
