"""State derivatives from sampled, quantized position (seed 000 §4.1 and a robust default).

Two methods give the states ``x = [θ, ω]``, their derivatives ``ẋ = [ω, α]`` and the
inputs aligned to them:

``paper``
    Seed 000 §4.1: forward Euler differences, ``ω_k = (θ_{k+1} − θ_k)/Δt`` and
    ``α_k = (ω_{k+1} − ω_k)/Δt``; inputs are used as sampled. Each difference of a
    quantized angle carries quantization noise of order ``q/Δt`` (``q`` the encoder step),
    and the second difference ``q/Δt²``.

``default``
    Kernel (modulating-function) filtering: the angle and the inputs are all convolved
    with the same smooth, compact kernel ``g`` and the derivatives fall on the kernel,
    ``(g∗θ)' = g'∗θ`` and ``(g∗θ)'' = g''∗θ``. Because the same linear filter is applied to
    every signal of the linear equation ``J·θ'' + D·θ' + C·θ = Kt·i``, the filtered signals
    obey the same equation with the same parameters, so the filter removes noise (of the
    quantized angle and of the current sensor) without biasing the estimates. Nothing
    quantized is differentiated. ``g(s) = (1 − (s/T)²)⁴`` on ``|s| < T`` is three times
    continuously differentiable, so ``g''`` vanishes smoothly at the ends. The filter is
    centred (no lag); ``half_width`` samples are dropped at each end.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import numpy as np
from scipy import ndimage

from stand.errors import InputError
from stand.ident.noise import noise_sigma

Method = Literal["default", "paper"]
METHODS: tuple[str, ...] = ("default", "paper")
#: Half width of the default kernel, samples (its support is 2·HALF_WIDTH + 1 samples).
DEFAULT_HALF_WIDTH = 8
#: Largest share of the filtered input's variance that its filtered white noise may have
#: when the half width is chosen automatically; it bounds the errors-in-variables bias
#: of the input's coefficient (Kt/J) to about this fraction.
MAX_NOISE_FRACTION = 0.01
#: Longest automatic half width as a fraction of the record.
MAX_HALF_WIDTH_FRACTION = 0.05
#: Smallest half width that still samples g'' with its two lobes, samples.
MIN_HALF_WIDTH = 2
#: Power of the kernel (1 − s²)^KERNEL_POWER; 4 makes g'' vanish smoothly at the ends.
KERNEL_POWER = 4


@dataclass(frozen=True)
class States:
    """States, derivatives and inputs on a common set of samples.

    Attributes
    ----------
    theta : ndarray, shape (..., samples)
        Angle θ (filtered for ``default``), rad.
    omega : ndarray, shape (..., samples)
        Angular velocity ω = θ', rad/s.
    alpha : ndarray, shape (..., samples)
        Angular acceleration α = θ'', rad/s².
    inputs : ndarray, shape (..., samples, nu)
        Inputs treated as ``theta`` (filtered for ``default``), in their own units.
    first : int
        Index of the first input sample the rows correspond to (centre for ``default``);
        for ``default`` also the kernel's half width, samples.
    method : str
        The method used.
    """

    theta: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    inputs: np.ndarray
    first: int
    method: str

    @property
    def x(self) -> np.ndarray:
        """States ``[θ, ω]``, shape (..., samples, 2)."""
        return np.stack([self.theta, self.omega], axis=-1)

    @property
    def xdot(self) -> np.ndarray:
        """Derivatives ``[ω, α]``, shape (..., samples, 2)."""
        return np.stack([self.omega, self.alpha], axis=-1)


def kernel(half_width: int, dt_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The default kernel and its first two derivatives, sampled at ``k·dt_s``.

    Returns ``(g, g1, g2)`` scaled so that ``Σ g·Δt = 1``; ``g1`` and ``g2`` are the exact
    derivatives of the same continuous function (1/s and 1/s²), with the same scale.
    """
    if half_width < MIN_HALF_WIDTH:
        raise InputError(f"half_width must be >= {MIN_HALF_WIDTH} samples, got {half_width}")
    T = (half_width + 1) * dt_s
    s = np.arange(-half_width, half_width + 1) * dt_s / T
    p = KERNEL_POWER
    base = 1.0 - s * s
    g = base**p
    g1 = -2 * p * s * base ** (p - 1) / T
    g2 = (-2 * p * base ** (p - 1) + 4 * p * (p - 1) * s * s * base ** (p - 2)) / T**2
    scale = 1.0 / (g.sum() * dt_s)
    g, g1, g2 = g * scale, g1 * scale, g2 * scale
    # The sampled sums obey the moments of the continuous kernel only approximately; make
    # them exact (a small correction in the span of g·{1, τ, τ²}) so that g1∗θ and g2∗θ are
    # the exact first and second derivatives of g∗θ for any quadratic θ (angle offsets and
    # ramps leak nothing into ω and α).
    tau = np.arange(-half_width, half_width + 1) * dt_s
    g1 = g1 + _moment_correction(g1, g, tau, dt_s, [0.0, -1.0])
    g2 = g2 + _moment_correction(g2, g, tau, dt_s, [0.0, 0.0, 2.0])
    return g, g1, g2


def interval_weights(half_width: int, dt_s: float) -> np.ndarray:
    """Weights of the default kernel for values held over sample periods.

    A signal that holds ``v[k]`` over the period from sample ``k`` to ``k + 1`` (a
    current settled by a drive's fast loop, a mean over the period) gives, through the
    continuous kernel, ``Σ_j W[j]·v[n − j]`` at sample ``n`` with
    ``W[j] = ∫ g(τ) dτ`` over ``((j − 1)·Δt, j·Δt)``, ``j = −half_width … half_width + 1``.
    Exact for such signals, where treating the held value as a sample at ``k`` would
    misplace it by half a period. Scaled like :func:`kernel` (its ``Σ g·Δt = 1``).
    """
    T = (half_width + 1) * dt_s
    p = np.polynomial.Polynomial([1.0, 0.0, -1.0]) ** KERNEL_POWER
    antiderivative = p.integ()
    s = np.clip(np.arange(-half_width - 1, half_width + 2) * dt_s / T, -1.0, 1.0)
    raw = T * np.diff(antiderivative(s))
    g_raw = (1.0 - (np.arange(-half_width, half_width + 1) * dt_s / T) ** 2) ** KERNEL_POWER
    return np.asarray(raw / (g_raw.sum() * dt_s))


@lru_cache(maxsize=16)
def acceleration_kernel(half_width: int, dt_s: float) -> np.ndarray:
    """What the sampled second-derivative kernel makes of the acceleration, at the knots.

    The filtered acceleration is a sum over the samples, ``α_f(t_n) = Σ_k g2[k]·Δt·θ(t_n −
    kΔt)``, not the integral ``∫ g(s)·θ''(t_n − s) ds`` it approximates. Writing
    ``θ(t) = θ(t₀) + θ'(t₀)·(t − t₀) + ∫ (t − u)₊·θ''(u) du`` (the first two terms vanish
    under the kernel's moments) gives, for any motion, ``α_f(t_n) = ∫ K(s)·θ''(t_n − s) ds``
    with ``K(s) = Σ_k g2[k]·Δt·(s − kΔt)₊``: piecewise linear between the sample instants,
    zero outside ``(−h, h + 1)·Δt``, of unit area. Filtering the model's torques with
    ``K`` instead of ``g`` makes the filtered equation hold exactly where the acceleration
    is held over each period; with ``g`` the difference is of order ``(Δt/T)³`` of the
    current's steps (Kt/J +0.02–0.03 % at ``h`` = 8 on a noise-free, unquantized PRBS).

    Returns
    -------
    ndarray, shape (2·half_width + 1,)
        ``K(jΔt)`` for ``j = −half_width … half_width``, 1/s (``K`` is zero at the ends of
        its support). Read-only: one array per ``(half_width, dt_s)`` is kept (a run's
        columns all go through the same kernel; at ``h`` = 1000 one evaluation is 20 ms).
    """
    _, _, g2 = kernel(half_width, dt_s)
    knots = np.arange(-half_width, half_width + 1)
    out = np.asarray([np.sum(g2 * dt_s * np.maximum(j - knots, 0) * dt_s) for j in knots])
    out.flags.writeable = False
    return out


def acceleration_interval_weights(half_width: int, dt_s: float) -> np.ndarray:
    """:func:`interval_weights` of :func:`acceleration_kernel`: ``∫ K(s) ds`` over
    ``((j − 1)·Δt, j·Δt)``, ``j = −half_width … half_width + 1`` (``K`` is linear there)."""
    knots = np.concatenate([[0.0], acceleration_kernel(half_width, dt_s), [0.0]])
    return np.asarray(0.5 * dt_s * (knots[:-1] + knots[1:]))


def filter_held(values: np.ndarray, half_width: int, dt_s: float,
                weights: np.ndarray | None = None) -> np.ndarray:
    """Values held over each period (``values[k]`` from sample ``k`` to ``k + 1``) through
    the continuous default kernel (or the period ``weights`` given, ``j = −h … h + 1``),
    at the samples where the kernel fits (as :func:`_convolve_valid`)."""
    w = interval_weights(half_width, dt_s) if weights is None else weights  # j = −h … h + 1
    v = np.concatenate([values[:1], values])           # v[−1] taken as v[0]
    n = len(values)
    out = np.zeros(n - 2 * half_width)
    for j, weight in zip(range(-half_width, half_width + 2), w, strict=True):
        # row n (from h to N − 1 − h) takes v[n − j], shifted by one for the padding
        out += weight * v[half_width - j + 1: n - half_width - j + 1]
    return out


def _moment_correction(w: np.ndarray, g: np.ndarray, tau: np.ndarray, dt_s: float,
                       targets: list[float]) -> np.ndarray:
    """Correction ``c(τ)·g`` (c a polynomial) so that ``Σ w·τᵐ·Δt`` equals ``targets[m]``."""
    m = len(targets)
    basis = np.array([g * tau**k for k in range(m)])               # (m, taps)
    moments = np.array([[np.sum(b * tau**j) * dt_s for b in basis] for j in range(m)])
    error = np.array(targets) - np.array([np.sum(w * tau**j) * dt_s for j in range(m)])
    return np.asarray(np.linalg.solve(moments, error) @ basis)


def auto_half_width(inputs: np.ndarray, noise: float) -> int:
    """Smallest kernel half width at which the filtered input noise is negligible.

    Tries half widths from ``DEFAULT_HALF_WIDTH`` upwards (×1.5 each) and returns the
    first at which ``noise²·Σg²`` (the variance white noise of standard deviation
    ``noise`` keeps after the kernel) is at most ``MAX_NOISE_FRACTION`` of the variance of
    the filtered input; the longest tried is ``MAX_HALF_WIDTH_FRACTION`` of the record.

    Parameters
    ----------
    inputs : ndarray, shape (samples,)
        The input (e.g. current), in its unit.
    noise : float
        Standard deviation of its white noise, same unit.
    """
    u = np.asarray(inputs, dtype=float)
    longest = max(DEFAULT_HALF_WIDTH, int(MAX_HALF_WIDTH_FRACTION * len(u)))
    h = DEFAULT_HALF_WIDTH
    while True:
        g, _, _ = kernel(h, 1.0)                       # Σg = 1 at unit sample period
        filtered = _convolve_valid(u, g, 1.0)
        if noise**2 * float(np.sum(g * g)) <= MAX_NOISE_FRACTION * float(np.var(filtered)):
            return h
        if h >= longest:
            return longest
        h = min(longest, int(np.ceil(1.5 * h)))


def _convolve_valid(signal: np.ndarray, weights: np.ndarray, dt_s: float) -> np.ndarray:
    """``Σ_j signal[k − j]·w[j]·Δt`` at the samples where the kernel fits, along axis -1."""
    h = (len(weights) - 1) // 2
    out = ndimage.convolve1d(signal, weights * dt_s, axis=-1, mode="nearest")
    return out[..., h:signal.shape[-1] - h]


def state_derivatives(position_rad: np.ndarray, inputs: np.ndarray, dt_s: float,
                      method: str = "default", half_width: int | None = DEFAULT_HALF_WIDTH,
                      noise: float | None = None) -> States:
    """States, derivatives and aligned inputs from a sampled angle.

    Parameters
    ----------
    position_rad : ndarray, shape (..., samples)
        Unwrapped shaft angle, rad (may be quantized).
    inputs : ndarray, shape (..., samples) or (..., samples, nu)
        Inputs sampled with the angle (e.g. current, A).
    dt_s : float
        Sample period, s.
    method : {'default', 'paper'}
        See the module docstring.
    half_width : int or None
        Half width of the ``default`` kernel, samples; ``None`` chooses it from the noise
        of the first input (:func:`auto_half_width`).
    noise : float, optional
        White-noise standard deviation of the first input for the automatic half width
        (default: estimated from its sample-to-sample differences).

    Returns
    -------
    States
    """
    if method not in METHODS:
        raise InputError(f"method must be one of {', '.join(METHODS)}, not {method!r}")
    if not dt_s > 0:
        raise InputError(f"dt_s must be > 0 s, got {dt_s}")
    theta = np.asarray(position_rad, dtype=float)
    u = np.asarray(inputs, dtype=float)
    if u.ndim == theta.ndim:
        u = u[..., None]
    if u.shape[:-1] != theta.shape:
        raise InputError(f"inputs {u.shape} do not match position {theta.shape} sample for sample")
    n = theta.shape[-1]
    if method == "paper":
        omega = np.diff(theta, axis=-1) / dt_s
        alpha = np.diff(omega, axis=-1) / dt_s
        m = n - 2
        return States(theta[..., :m], omega[..., :m], alpha, u[..., :m, :], 0, "paper")
    if half_width is None:
        first = u.reshape(-1, n, u.shape[-1])[0, :, 0]
        half_width = auto_half_width(first, noise_sigma(first) if noise is None else noise)
    if n < 2 * half_width + 2:
        half_width = max(MIN_HALF_WIDTH, (n - 2) // 2)
    g, g1, g2 = kernel(half_width, dt_s)
    u_last = np.moveaxis(u, -1, -2)  # (..., nu, samples)
    u_f = np.moveaxis(_convolve_valid(u_last, g, dt_s), -2, -1)
    return States(
        _convolve_valid(theta, g, dt_s), _convolve_valid(theta, g1, dt_s),
        _convolve_valid(theta, g2, dt_s), u_f, half_width, "default",
    )
