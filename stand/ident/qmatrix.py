"""The Q-matrix equation-error solver of seed 000 eqs. 6-10, batched and streaming.

For measured states ``x_d``, their derivatives ``ẋ_d`` and inputs ``u_d``, the matrices
``A_e``, ``B_e`` that minimise ``∫ dᵀd dt`` with ``d = ẋ_d − (A x_d + B u_d)`` (eqs. 6-7)
solve the normal equations 8-9, written in eq. 10 as::

    [A_e  B_e] = [Q1  Q2] · [[Q11, Q12], [Q12ᵀ, Q22]]⁻¹

    Q1 = ∫ ẋ xᵀ,  Q2 = ∫ ẋ uᵀ,  Q11 = ∫ x xᵀ,  Q12 = ∫ x uᵀ,  Q22 = ∫ u uᵀ

All five are blocks of one Gram matrix ``G = ∫ w wᵀ dt`` of the stacked sample vector
``w = [ẋ; x; u; 1]``. :class:`QSums` keeps ``G`` (plus the sample count), so

- one pass over the samples (one BLAS matrix product, no Python loop over samples) gives
  every Q; the extra rows give ``∫ẋẋᵀ`` and ``∫ẋ`` for the residual, the fit and the
  standard errors without a second pass;
- sums over chunks add up (:meth:`QSums.add`, :meth:`QSums.merge`), so a recording of any
  length is identified in constant memory and gives the same answer as one pass;
- leading axes are batch axes: ``x`` shaped ``(runs, samples, nx)`` gives ``runs``
  independent problems solved together.

Any numbers of states ``nx`` and inputs ``u`` work, so extra regressors (``sign(ω)``,
``sin(Nθ)``, ``cos(Nθ)``, ``1``) plug in as extra input columns.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from stand.errors import InputError, NotExcitedError

#: Largest condition number of the equilibrated regressor matrix that is still solved;
#: beyond it the columns are dependent to working precision.
COND_LIMIT = 1e10
#: Values stacked per chunk by :meth:`QSums.add` (about 1 MB: stays in cache).
CHUNK_VALUES = 1 << 17
#: Fewest samples per chunk (keeps the per-chunk overhead small for large batches).
MIN_CHUNK_SAMPLES = 512
#: Fewest samples beyond the number of unknowns per row (residual degrees of freedom).
MIN_DOF = 3


@dataclass
class QSums:
    """Running sums of seed 000 eq. 10, over one or many runs.

    Attributes
    ----------
    nx, nu : int
        Numbers of states and inputs.
    G : ndarray, shape (..., nx+nx+nu+1, nx+nx+nu+1)
        ``Σ w wᵀ Δt`` of ``w = [ẋ; x; u; 1]``; leading axes are batch axes.
    samples : ndarray of int, shape (...)
        Samples accumulated.
    """

    nx: int
    nu: int
    G: np.ndarray
    samples: np.ndarray = field(default_factory=lambda: np.zeros((), dtype=np.int64))

    @classmethod
    def zeros(cls, nx: int, nu: int, batch: tuple[int, ...] = ()) -> QSums:
        """Empty sums for ``nx`` states and ``nu`` inputs, with batch shape ``batch``."""
        if nx < 1 or nu < 0:
            raise InputError(f"QSums: need nx >= 1 and nu >= 0, got nx={nx}, nu={nu}")
        size = 2 * nx + nu + 1
        return cls(nx, nu, np.zeros((*batch, size, size)), np.zeros(batch, dtype=np.int64))

    @property
    def width(self) -> int:
        """Length of the stacked sample vector ``w = [ẋ; x; u; 1]``."""
        return 2 * self.nx + self.nu + 1

    def _slices(self) -> tuple[slice, slice, slice]:
        nx, nu = self.nx, self.nu
        return slice(0, nx), slice(nx, 2 * nx), slice(2 * nx, 2 * nx + nu)

    @property
    def Q1(self) -> np.ndarray:
        """``∫ ẋ xᵀ dt``, shape (..., nx, nx)."""
        y, x, _ = self._slices()
        return self.G[..., y, x]

    @property
    def Q2(self) -> np.ndarray:
        """``∫ ẋ uᵀ dt``, shape (..., nx, nu)."""
        y, _, u = self._slices()
        return self.G[..., y, u]

    @property
    def Q11(self) -> np.ndarray:
        """``∫ x xᵀ dt``, shape (..., nx, nx)."""
        _, x, _ = self._slices()
        return self.G[..., x, x]

    @property
    def Q12(self) -> np.ndarray:
        """``∫ x uᵀ dt``, shape (..., nx, nu)."""
        _, x, u = self._slices()
        return self.G[..., x, u]

    @property
    def Q22(self) -> np.ndarray:
        """``∫ u uᵀ dt``, shape (..., nu, nu)."""
        _, _, u = self._slices()
        return self.G[..., u, u]

    def add(self, xdot: np.ndarray, x: np.ndarray, u: np.ndarray, dt_s: float = 1.0) -> QSums:
        """Accumulate samples in place and return ``self``.

        Parameters
        ----------
        xdot, x : ndarray, shape (..., samples, nx)
            State derivatives and states; the leading axes must equal the batch shape.
        u : ndarray, shape (..., samples, nu)
            Inputs.
        dt_s : float
            Sample period, s: the weight of each sample in the integrals (it cancels in
            eq. 10 for uniform sampling).
        """
        xdot, x, u = (np.asarray(a, dtype=float) for a in (xdot, x, u))
        n = x.shape[-2] if x.ndim >= 2 else -1
        for name, a, cols in (("xdot", xdot, self.nx), ("x", x, self.nx), ("u", u, self.nu)):
            if a.ndim < 2 or a.shape[-1] != cols or a.shape[-2] != n:
                raise InputError(
                    f"QSums.add: {name} must be shaped (..., samples, {cols}) with the same "
                    f"samples as x, got {a.shape}"
                )
        batch = np.broadcast_shapes(xdot.shape[:-2], x.shape[:-2], u.shape[:-2])
        runs = int(np.prod(batch, dtype=np.int64))
        step = max(MIN_CHUNK_SAMPLES, CHUNK_VALUES // max(1, runs * self.width))
        w = np.empty((*batch, min(n, step), self.width))
        w[..., -1] = 1.0
        parts = [np.broadcast_to(a, (*batch, n, a.shape[-1])) for a in (xdot, x, u)]
        for start in range(0, n, step):  # stacked chunk by chunk: bounded, cache-sized copy
            chunk = w[..., :min(n, start + step) - start, :]
            np.concatenate([a[..., start:start + step, :] for a in parts], axis=-1,
                           out=chunk[..., :-1])
            self.add_stacked(chunk, dt_s)
        return self

    def add_stacked(self, w: np.ndarray, dt_s: float = 1.0) -> QSums:
        """Accumulate samples already stacked as ``w = [ẋ, x, u, 1]``, shape (..., samples, width).

        The fast path for callers that build ``w`` themselves (no copy here).
        """
        if w.ndim < 2 or w.shape[-1] != self.width:
            raise InputError(f"QSums.add_stacked: w must be (..., samples, {self.width}), got {w.shape}")
        gram = np.matmul(np.swapaxes(w, -1, -2), w)
        if gram.shape != self.G.shape:
            raise InputError(
                f"QSums.add: data of batch shape {gram.shape[:-2]} do not match the sums' "
                f"batch shape {self.G.shape[:-2]}"
            )
        self.G += dt_s * gram
        self.samples = self.samples + w.shape[-2]
        return self

    def merge(self, other: QSums) -> QSums:
        """New sums holding the samples of ``self`` and ``other``."""
        if (self.nx, self.nu) != (other.nx, other.nu):
            raise InputError(
                f"QSums.merge: nx, nu differ: ({self.nx}, {self.nu}) and ({other.nx}, {other.nu})"
            )
        return QSums(self.nx, self.nu, self.G + other.G, self.samples + other.samples)

    def __getitem__(self, index: int | slice | tuple[int | slice, ...]) -> QSums:
        """The sums of one run (or a slice of runs) of a batch."""
        return QSums(self.nx, self.nu, self.G[index], np.asarray(self.samples[index]))


@dataclass(frozen=True)
class QResult:
    """Solution of eq. 10, with its figures of merit (leading axes: batch).

    Attributes
    ----------
    A : ndarray, shape (..., nx, nx)
        System matrix ``A_e``.
    B : ndarray, shape (..., nx, nu)
        Input matrix ``B_e``.
    A_se, B_se : ndarray
        Standard errors of each element, from the residual variance of its row and the
        inverse normal matrix (white equation error assumed; with coloured residuals,
        e.g. after filtering, they are optimistic: compare with repeat scatter).
    fit_percent : ndarray, shape (..., nx)
        Equation-error fit of each state row, ``100·(1 − ‖ẋ − ẋ̂‖ / ‖ẋ − mean ẋ‖)``, %.
    residual_rms : ndarray, shape (..., nx)
        RMS equation error of each row, in the unit of that ẋ.
    condition_number : ndarray, shape (...)
        2-norm condition number of ``[[Q11, Q12], [Q12ᵀ, Q22]]`` after scaling each
        regressor to unit RMS (so it does not depend on units).
    samples : ndarray of int, shape (...)
        Samples used.
    """

    A: np.ndarray
    B: np.ndarray
    A_se: np.ndarray
    B_se: np.ndarray
    fit_percent: np.ndarray
    residual_rms: np.ndarray
    condition_number: np.ndarray
    samples: np.ndarray
    message: str = ""


def solve(sums: QSums, check: bool = True, names: list[str] | None = None) -> QResult:
    """Solve eq. 10 for every problem held in ``sums``.

    Parameters
    ----------
    sums : QSums
        Accumulated sums.
    check : bool
        Raise :class:`~stand.errors.NotExcitedError` when any problem cannot be solved
        (too few samples, a regressor that is identically zero, dependent regressors).
        With ``False`` such problems give NaN estimates instead.
    names : list of str, optional
        Names of the regressors (states, then inputs) for error messages.

    Returns
    -------
    QResult
    """
    nx, nu = sums.nx, sums.nu
    nz = nx + nu
    G = sums.G
    y, z = slice(0, nx), slice(nx, nx + nz)
    M = G[..., z, z]                     # [[Q11, Q12], [Q12ᵀ, Q22]]
    R = G[..., y, z]                     # [Q1, Q2]
    samples = np.asarray(sums.samples)
    diag = np.diagonal(M, axis1=-2, axis2=-1)
    dead = ~(diag > 0)
    scale = 1.0 / np.sqrt(np.where(dead, 1.0, diag))
    Ms = M * scale[..., :, None] * scale[..., None, :]
    singular_values = np.linalg.svd(Ms, compute_uv=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = singular_values[..., 0] / singular_values[..., -1]
    cond = np.where(dead.any(axis=-1) | ~np.isfinite(cond), np.inf, cond)
    bad = (cond > COND_LIMIT) | (samples < nz + MIN_DOF)
    if check and np.any(bad):
        raise NotExcitedError(_not_excited_message(sums, bad, dead, cond, names))
    safe = np.where(bad[..., None, None], np.eye(nz), Ms)
    Ms_inv = np.linalg.inv(safe)
    M_inv = Ms_inv * scale[..., :, None] * scale[..., None, :]
    theta = np.matmul(R, M_inv)          # eq. 10: [A B] = [Q1 Q2] M⁻¹
    # Residual sums: ∫ddᵀ = ∫ẋẋᵀ − Θ Rᵀ (diagonal only), total sums about the mean.
    Qyy = np.diagonal(G[..., y, y], axis1=-2, axis2=-1)
    rss = Qyy - np.einsum("...ij,...ij->...i", theta, R)
    rss = np.maximum(rss, 0.0)
    total_time = G[..., -1, -1]
    ysum = G[..., y, -1]
    with np.errstate(divide="ignore", invalid="ignore"):
        tss = Qyy - ysum**2 / total_time[..., None]
        fit = 100.0 * (1.0 - np.sqrt(rss / tss))
        dof = np.maximum(samples - nz, 1)
        sigma2 = rss / dof[..., None]                      # per row, weighted units
        var = sigma2[..., :, None] * np.diagonal(M_inv, axis1=-2, axis2=-1)[..., None, :]
        residual_rms = np.sqrt(rss / total_time[..., None])
    se = np.sqrt(np.maximum(var, 0.0))
    nan = np.where(bad, np.nan, 0.0)
    theta = theta + nan[..., None, None]
    se = se + nan[..., None, None]
    return QResult(
        A=theta[..., :, :nx], B=theta[..., :, nx:], A_se=se[..., :, :nx], B_se=se[..., :, nx:],
        fit_percent=fit + nan[..., None], residual_rms=residual_rms + nan[..., None],
        condition_number=cond, samples=samples,
        message="solved" if not np.any(bad) else f"{int(np.sum(bad))} problem(s) not excited",
    )


def _not_excited_message(sums: QSums, bad: np.ndarray, dead: np.ndarray,
                         cond: np.ndarray, names: list[str] | None) -> str:
    index = tuple(int(i) for i in np.argwhere(np.atleast_1d(bad))[0]) if bad.ndim else ()
    where = f"run {index[0] if len(index) == 1 else index}: " if index else ""
    nz = sums.nx + sums.nu
    n = int(np.asarray(sums.samples)[index]) if index else int(sums.samples)
    if n < nz + MIN_DOF:
        return (f"{where}{n} samples cannot determine {nz} unknowns per row; record at least "
                f"{nz + MIN_DOF} samples")
    if names is None or len(names) != nz:
        names = [f"x{k + 1}" for k in range(sums.nx)] + [f"u{k + 1}" for k in range(sums.nu)]
    zero = [names[k] for k in np.flatnonzero(np.atleast_2d(dead)[index if index else 0])]
    if zero:
        return (f"{where}regressor(s) {', '.join(zero)} are zero throughout: the data do not "
                "excite the model (motor at rest or no input); excite it with a varying command")
    c = float(np.asarray(cond)[index]) if index else float(cond)
    return (f"{where}the regressors are linearly dependent (condition number {c:.3g} > "
            f"{COND_LIMIT:.0e}): the data do not excite the model (e.g. constant current at "
            "constant speed); excite it with a varying command")
