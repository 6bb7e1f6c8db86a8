"""Fleet figures of a batch: pooled Q sums and the spread of one figure over a group.

**Pooled estimate** (``identify``). The sums of seed 000 eq. 10 are integrals over the
samples, so the sums of several runs add up to those of one long record: solving the
summed ``G`` gives the fleet's Kt/J, D/J, C/J — the least-squares model of every sample
of the group at once, each run weighted by its excitation (its share of ``∫ x xᵀ`` and
``∫ u uᵀ``). Its standard errors assume white equation error and one model for all runs;
with units that differ, the spread below says by how much.

**Fleet spread** (every operation with a fleet field). Over the ``n`` runs of a group
that gave a result: mean and its 95 % Student-t interval, sample standard deviation
``s`` and its 95 % interval from the χ² distribution of ``(n−1)s²/σ²`` (normal units
assumed). ``s`` holds both the unit-to-unit spread and each run's estimation noise;
``noise_se`` (RMS of the per-run standard errors, when the result has one) says how
much of it is noise.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from stand.batch.operations import Outcome
from stand.errors import NotExcitedError

#: Confidence of the intervals.
LEVEL = 0.95


@dataclass(frozen=True)
class Fleet:
    """Fleet figures of one group.

    Attributes
    ----------
    group : str
        The group (a profile, a folder, ...).
    field : str
        The result field summarized (e.g. ``Kt_over_J``; its unit is the field's).
    runs : int
        Items of the group with a result; ``errors`` the others.
    mean, std : float or None
        Mean and sample standard deviation over those items (``std`` needs two).
    mean_ci95, std_ci95 : list of float or None
        95 % intervals of the mean (Student t) and of the standard deviation (χ²).
    noise_se : float or None
        RMS of the per-run standard errors of the field, when the results carry them.
    pooled : dict or None
        ``identify`` only: ``Kt_over_J``, ``D_over_J``, ``C_over_J`` (rad/(s²·A), 1/s,
        1/s²) of the summed Q sums, their standard errors ``*_se``, ``fit_percent``,
        ``condition_number`` and ``samples``; ``None`` when the sums do not determine the
        model (``message`` says why).
    message : str
        What was not computed and why.
    """

    group: str
    field: str
    runs: int
    errors: int
    mean: float | None
    std: float | None
    mean_ci95: list[float] | None
    std_ci95: list[float] | None
    noise_se: float | None
    pooled: dict[str, float] | None
    message: str = ""

    def to_json(self) -> dict[str, object]:
        """Plain JSON data (``None`` for what was not computed)."""
        from stand.jsonable import to_jsonable

        data: dict[str, object] = to_jsonable(self)
        return data


def fleets(outcomes: Sequence[Outcome], groups: Sequence[str], field: str) -> list[Fleet]:
    """Fleet figures of every group, in order of first appearance.

    Parameters
    ----------
    outcomes : sequence of Outcome
        In item order.
    groups : sequence of str
        The group of each item ("" items are not pooled).
    field : str
        The result field to summarize.
    """
    order: dict[str, list[Outcome]] = {}
    for outcome, group in zip(outcomes, groups, strict=True):
        if group:
            order.setdefault(group, []).append(outcome)
    return [_fleet(group, members, field) for group, members in order.items()]


def _fleet(group: str, members: list[Outcome], field: str) -> Fleet:
    ok = [m for m in members if m.result is not None and m.result.get(field) is not None]
    values = np.array([float(m.result[field]) for m in ok])  # type: ignore[index]
    n = len(values)
    notes = []
    mean = float(values.mean()) if n else None
    std = mean_ci = std_ci = None
    if n >= 2:
        std = float(values.std(ddof=1))
        half = float(stats.t.ppf(0.5 + LEVEL / 2, n - 1)) * std / math.sqrt(n)
        mean_ci = [mean - half, mean + half]  # type: ignore[operator]
        std_ci = [std * math.sqrt((n - 1) / float(stats.chi2.ppf(0.5 + LEVEL / 2, n - 1))),
                  std * math.sqrt((n - 1) / float(stats.chi2.ppf(0.5 - LEVEL / 2, n - 1)))]
    else:
        notes.append(f"spread needs two results, the group has {n}")
    ses = [m.result.get(field + "_se") for m in ok]  # type: ignore[union-attr]
    noise_se = (float(np.sqrt(np.mean(np.square(np.array(ses, dtype=float)))))
                if ses and None not in ses else None)
    pooled = None
    sums = [(m.sums, m.sum_samples) for m in ok if m.sums is not None]
    if sums:
        pooled, note = _pooled(sums)
        notes += [note] if note else []
    return Fleet(group, field, n, len(members) - n, mean, std, mean_ci, std_ci, noise_se,
                 pooled, "; ".join(notes))


def _pooled(sums: list[tuple[np.ndarray, int]]) -> tuple[dict[str, float] | None, str]:
    """Solve eq. 10 on the sums ``(G, samples)`` of all runs, added in item order (so
    every path that computes the same sums gives the same bits)."""
    from stand.ident.qmatrix import QSums, solve

    total = np.zeros_like(sums[0][0])
    for G, _ in sums:
        total += G
    samples = np.asarray(sum(n for _, n in sums), dtype=np.int64)
    try:
        q = solve(QSums(2, 1, total, samples), names=["angle θ", "speed ω", "current i"])
    except NotExcitedError as exc:
        return None, f"pooled sums: {exc}"
    return {
        "Kt_over_J": float(q.B[1, 0]), "D_over_J": -float(q.A[1, 1]),
        "C_over_J": -float(q.A[1, 0]), "Kt_over_J_se": float(q.B_se[1, 0]),
        "D_over_J_se": float(q.A_se[1, 1]), "C_over_J_se": float(q.A_se[1, 0]),
        "fit_percent": float(q.fit_percent[1]), "condition_number": float(q.condition_number),
        "samples": int(q.samples), "runs": len(sums),
    }, ""
