"""Instrumental-variable estimate, block cross-validation and block-sandwich intervals.

For the output ``y``, regressors ``X`` and instruments ``Z`` (``Z = X`` gives least
squares), the estimate solves ``Zᵀ(y − X·β) = 0``. Everything comes from the Gram
matrices of ``[y, X, Z]`` over ``B`` contiguous blocks of the run:

- **Uncertainty.** The residuals of a filtered equation error are coloured (the kernel
  alone correlates them over its support, and unmodelled dynamics over longer). The
  covariance is the sandwich ``H⁻¹·S·H⁻ᵀ`` with ``H = ZᵀX`` and ``S`` the sum over blocks
  of the outer products of the block scores ``Z_bᵀ·e_b`` (a cluster-robust, or
  batch-means, estimate: right for any correlation shorter than a block), scaled by
  ``B/(B − 1)``. Intervals use Student's t with ``B − 1`` degrees of freedom: with few
  blocks the variance itself is uncertain, and t widens the interval for it.
- **Cross-validation.** Leaving out block ``b`` (its Gram matrix subtracted from the
  total) gives an estimate whose equation error on block ``b`` is the held-out error of
  that block; the effect selection (:mod:`stand.ident.select`) compares models by it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import t as student_t

from stand.errors import NotExcitedError

#: Blocks of a run for the sandwich and the cross-validation.
BLOCKS = 16
#: Fewest blocks (a run too short for ``BLOCKS`` long blocks uses fewer, down to this).
MIN_BLOCKS = 8
#: Shortest block, in kernel supports: blocks much longer than the filter's memory keep
#: the block scores nearly independent.
MIN_BLOCK_SUPPORTS = 2
#: Largest condition number of the equilibrated ``ZᵀX`` that is still solved.
COND_LIMIT = 1e10
#: Two-sided confidence level of the intervals.
CONFIDENCE = 0.95


@dataclass(frozen=True)
class Estimate:
    """Solution of ``Zᵀ(y − Xβ) = 0`` with its block-sandwich covariance.

    Attributes
    ----------
    names : list of str
        Column names of ``X``.
    beta : ndarray, shape (p,)
        Coefficients, in the unit of ``y`` per unit of each column.
    cov : ndarray, shape (p, p)
        Block-sandwich covariance of ``beta``.
    dof : int
        Degrees of freedom of the t quantile (blocks − 1).
    fit_percent : float
        ``100·(1 − ‖y − Xβ‖/‖y − ȳ‖)``, %.
    condition_number : float
        Of ``ZᵀX`` with every column scaled to unit RMS.
    samples : int
        Rows used.
    cv_sse : ndarray, shape (blocks,)
        Held-out squared equation error of each block (leave-one-block-out).
    """

    names: list[str]
    beta: np.ndarray
    cov: np.ndarray
    dof: int
    fit_percent: float
    condition_number: float
    samples: int
    cv_sse: np.ndarray

    @property
    def se(self) -> np.ndarray:
        """Standard errors of ``beta``."""
        return np.sqrt(np.maximum(np.diag(self.cov), 0.0))

    def value(self, name: str) -> float:
        """Coefficient of column ``name``."""
        return float(self.beta[self.names.index(name)])

    def with_variance(self, name: str, extra: float) -> Estimate:
        """This estimate with ``extra`` added to the variance of coefficient ``name``: an
        uncertainty the block sandwich does not see (which model describes the run, a
        scale of the input taken from elsewhere)."""
        k = self.names.index(name)
        cov = self.cov.copy()
        cov[k, k] += extra
        return replace(self, cov=cov)

    def expanded(self, names: list[str], restriction: np.ndarray) -> Estimate:
        """This estimate of a restricted fit (coefficients ``γ``, columns ``X·T``) as the
        coefficients ``β = T·γ`` of the columns ``names`` of ``X``, with the covariance
        ``T·V·Tᵀ`` (singular along the restriction)."""
        T = np.asarray(restriction, dtype=float)
        return replace(self, names=list(names), beta=T @ self.beta, cov=T @ self.cov @ T.T)

    def interval(self, name: str, sign: float = 1.0) -> list[float]:
        """95 % interval of ``sign·β[name]``, ``[low, high]``."""
        k = self.names.index(name)
        return t_interval(sign * float(self.beta[k]), float(self.se[k]), self.dof)


def t_quantile(dof: int) -> float:
    """The quantile of Student's t with ``dof`` degrees of freedom that a two-sided
    :data:`CONFIDENCE` interval reaches."""
    return float(student_t.ppf(0.5 + CONFIDENCE / 2, dof))


def t_interval(centre: float, se: float, dof: int) -> list[float]:
    """The :data:`CONFIDENCE` interval ``[low, high]`` of ``centre`` with standard error
    ``se``, Student's t with ``dof`` degrees of freedom."""
    half = t_quantile(dof) * se
    return [centre - half, centre + half]


def block_count(rows: int, support: int) -> int:
    """Blocks for ``rows`` rows and a filter support of ``support`` samples."""
    fitting = rows // max(1, MIN_BLOCK_SUPPORTS * support)
    return int(min(BLOCKS, max(MIN_BLOCKS, fitting)))


def block_grams(y: np.ndarray, X: np.ndarray, Z: np.ndarray, blocks: int) -> np.ndarray:
    """Gram matrices of ``[y, X, Z]`` over ``blocks`` contiguous blocks, (blocks, m, m)."""
    w = np.column_stack([y, X, Z])
    return np.stack([part.T @ part for part in np.array_split(w, blocks)])


def _parts(G: np.ndarray, p: int) -> tuple[np.ndarray, ...]:
    """``yᵀy``, ``Xᵀy``, ``XᵀX``, ``Zᵀy``, ``ZᵀX`` from Gram matrices (leading axes kept)."""
    x, z = slice(1, 1 + p), slice(1 + p, 1 + 2 * p)
    return G[..., 0, 0], G[..., x, 0], G[..., x, x], G[..., z, 0], G[..., z, x]


def solve_blocks(names: list[str], y: np.ndarray, X: np.ndarray, Z: np.ndarray,
                 blocks: int, source: str = "run", noise: np.ndarray | None = None) -> Estimate:
    """Estimate, covariance and held-out block errors of ``y ≈ X·β`` with instruments ``Z``.

    ``noise`` (with ``Z = X``): what the noise of the regressors adds to ``XᵀX`` over all
    rows; it is subtracted (bias-compensated least squares), from each block in
    proportion to its rows.

    Raises
    ------
    NotExcitedError
        Fewer rows than a few per unknown, a column that is zero throughout, or columns
        dependent to working precision.
    """
    p = X.shape[1]
    if len(y) < blocks * (p + 2):
        raise NotExcitedError(f"{source}: {len(y)} samples cannot determine {p} unknowns "
                              f"over {blocks} blocks; record a longer run")
    raw = block_grams(y, X, Z, blocks)
    Gb = raw.copy()
    if noise is not None and np.any(noise):
        share = np.array([len(part) for part in np.array_split(y, blocks)]) / len(y)
        for x in (slice(1, 1 + p), slice(1 + p, 1 + 2 * p)):
            for z in (slice(1, 1 + p), slice(1 + p, 1 + 2 * p)):
                Gb[:, x, z] -= share[:, None, None] * noise[None]
    G = Gb.sum(axis=0)
    yy, Xy, XX, Zy, ZX = _parts(raw.sum(axis=0), p)
    scale = np.sqrt(np.diag(XX))
    dead = [names[k] for k in np.flatnonzero(~(scale > 0))]
    if dead:
        raise NotExcitedError(f"{source}: regressor(s) {', '.join(dead)} are zero throughout: "
                              "the data do not excite the model; excite it with a varying command")
    zscale = np.sqrt(np.maximum(np.diag(G[1 + p:, 1 + p:]), np.finfo(float).tiny))
    _, _, _, Zy, ZX = _parts(G, p)
    H = ZX / zscale[:, None] / scale[None, :]
    singular = np.linalg.svd(H, compute_uv=False)
    cond = float(singular[0] / singular[-1]) if singular[-1] > 0 else np.inf
    if not cond <= COND_LIMIT:
        raise NotExcitedError(
            f"{source}: the columns {', '.join(names)} are linearly dependent (condition "
            f"number {cond:.3g} > {COND_LIMIT:.0e}): the data do not separate them; excite "
            "the motor with a varying command (both directions if friction is modelled)")
    beta = np.linalg.solve(ZX, Zy)
    scores = Gb[:, 1 + p:, 0] - Gb[:, 1 + p:, 1:1 + p] @ beta          # Z_bᵀ e_b
    H_inv = np.linalg.inv(ZX)
    S = scores.T @ scores * blocks / (blocks - 1)
    cov = H_inv @ S @ H_inv.T
    rss = max(float(yy - 2 * beta @ Xy + beta @ XX @ beta), 0.0)
    n = len(y)
    tss = float(yy - y.sum() ** 2 / n)
    fit = 100.0 * (1.0 - np.sqrt(rss / tss)) if tss > 0 else float("nan")
    return Estimate(names=names, beta=beta, cov=cov, dof=blocks - 1, fit_percent=float(fit),
                    condition_number=cond, samples=n, cv_sse=_held_out(Gb, G, raw, p))


def _held_out(Gb: np.ndarray, G: np.ndarray, raw: np.ndarray, p: int) -> np.ndarray:
    """Squared equation error of each block (its ``raw`` Gram matrix) under the estimate
    from the other blocks (their compensated ``Gb``)."""
    rest = G[None] - Gb
    _, _, _, Zy, ZX = _parts(rest, p)
    try:
        beta = np.linalg.solve(ZX, Zy[..., None])[..., 0]             # (blocks, p)
    except np.linalg.LinAlgError:
        return np.full(len(Gb), np.inf)
    yy, Xy, XX, _, _ = _parts(raw, p)
    sse = yy - 2 * np.einsum("bp,bp->b", beta, Xy) + np.einsum("bp,bpq,bq->b", beta, XX, beta)
    return np.asarray(np.maximum(sse, 0.0))
