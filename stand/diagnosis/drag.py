"""A drag continuous through zero speed: what a dry friction verdict is checked against.

Dry friction (Coulomb, Stribeck) is a torque that jumps with the sign of the speed. An
eddy-current brake, a fluid coupling, a seal on its oil film make a drag that grows
from zero with the speed and levels off (or falls again) over a speed scale the run
resolves. No vocabulary effect models it; beside the nominal model's viscous slope, a
dry friction level is what the selection names for it, and explains most of it.

So a verdict that names a dry friction meets a competitor, also where the gap it
leaves is within the noise gap (:func:`stand.diagnosis.noise.within_noise`: a size that
an eddy brake's difference from a friction level often stays within, while the paired
test on the simulated speed, which allows for the noise, still tells them apart): the
verdict's other effects and a drag ``T_d·tanh(ω/ω_d)`` in place of the friction,
``ω_d`` searched over :data:`SCALE_POINTS` speeds from :data:`LOW_SHARE` to
:data:`HIGH_SHARE` of the run's typical speed (each fitted on TRAIN and simulated on
TRAIN, the best kept; a best at either end is no fit: at the low end the drag is the
friction's jump, at the high end the viscous slope; an eddy-current brake
``T·2x/(1 + x²)``, ``x = ω/ω_c``, has the slope and the level of ``T·tanh(ω/ω_d)`` at
``ω_d = ω_c/2``). It wins over the friction where

- it simulates HOLDOUT significantly better than the verdict (the paired test on the
  simulated speed, as for a candidate effect,
  :func:`stand.diagnosis.selection.speed_improvement`),
- and the same search on HOLDOUT finds the same speed scale within :data:`SCALE_RATIO`.

What the stand has is then a drag that does not jump at reversal. The friction stays in
the verdict only where it still simulates HOLDOUT significantly better beside the drag
(a dry friction and a brake together); else the verdict drops it. A note names the
drag's speed scale, and the verdict ends in ``unexplained`` (CONTRACT §3: an effect
outside the vocabulary, beyond the noise by the paired test).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from stand.diagnosis.model import ModelSpec
from stand.diagnosis.scoring import Bench, Scored
from stand.diagnosis.selection import speed_improvement
from stand.diagnosis.signals import Signals
from stand.diagnosis.significance import PairedTest
from stand.effects.base import NO_FIT, Simulated, best, ratio_ok

#: What the note of a verdict that dropped a friction for a smooth drag says.
DROPPED = "dropped for a drag continuous through zero speed"
#: What it says where the friction stays beside the drag.
BESIDE = "has a drag continuous through zero speed beside it"
#: Speed scales searched per run, log-spaced between :data:`LOW_SHARE` and
#: :data:`HIGH_SHARE` of its typical speed.
SCALE_POINTS = 12
#: The lowest speed scale searched, as a share of the run's typical speed (the 95th
#: percentile of its filtered speed): a drag that levels off below it is a jump.
LOW_SHARE = 0.02
#: The highest, as that share: a drag still rising there is a viscous slope.
HIGH_SHARE = 3.0
#: TRAIN's and HOLDOUT's speed scales agree within this factor.
SCALE_RATIO = 2.0


@dataclass(frozen=True)
class Dragged:
    """The competitor that simulates HOLDOUT better than a dry friction verdict.

    Attributes
    ----------
    scored : Scored
        The verdict's other effects and the drag, identified on TRAIN, scored on
        HOLDOUT.
    without : Scored
        What the verdict keeps: its other effects alone, or the verdict itself where the
        friction stays beside the drag.
    test : PairedTest
        Its paired test against the verdict on HOLDOUT's simulated speed.
    friction : str
        The dry friction the verdict named.
    dropped : str or None
        The effect it replaced (``friction``), None where the friction stays.
    ws, holdout_ws : float
        Its speed scale on TRAIN and on HOLDOUT, rad/s.
    """

    scored: Scored
    without: Scored
    test: PairedTest
    friction: str
    dropped: str | None
    ws: float
    holdout_ws: float

    def note(self, verdict_gap: float) -> str:
        """Why the verdict drops the friction, or what it has beside it
        (``verdict_gap``: the gap with the friction, %)."""
        head = (f"{self.friction} {DROPPED}" if self.dropped is not None
                else f"{self.friction} {BESIDE}")
        tail = ("not a friction that jumps at reversal" if self.dropped is not None
                else "beside a friction that jumps at reversal (together they simulate "
                     "HOLDOUT better still)")
        return (f"{head}: T_d·tanh(ω/ω_d) with ω_d {self.ws:.3g} rad/s "
                f"({self.holdout_ws:.3g} rad/s on HOLDOUT) in its place simulates HOLDOUT "
                f"to {self.scored.gap:.2f} %, the friction to {verdict_gap:.2f} % "
                f"(p = {self.test.p_value:.2g}): a drag that grows from zero with the speed "
                f"(an eddy-current brake peaking near {2 * self.ws:.3g} rad/s, a fluid "
                f"coupling), {tail}; such a drag is not in the vocabulary")


def scales(base: ModelSpec, sig: Signals) -> list[ModelSpec]:
    """``base`` with a drag of each speed scale searched on ``sig`` (lowest first);
    none where the run does not move."""
    typical = float(np.percentile(np.abs(sig.omega_f), 95))
    if not typical > 0:
        return []
    return [replace(base, drag_ws=float(ws))
            for ws in np.geomspace(LOW_SHARE * typical, HIGH_SHARE * typical, SCALE_POINTS)]


def search(base: ModelSpec, sig: Signals, simulated: Simulated) -> ModelSpec:
    """The drag of :func:`scales` that simulates ``sig`` best among fits of a drag that
    opposes the motion; :data:`NO_FIT` at either end of the scales (an optimum the
    search does not bracket), where the run does not move, or where the speed crosses
    the drag's speed scale within a sample at its reversals (:func:`reversal_step`)."""
    grid = scales(base, sig)
    if not grid:
        return NO_FIT
    found = best(grid, sig, negative=("drag",), simulated=simulated)
    if found == NO_FIT or found.drag_ws in (grid[0].drag_ws, grid[-1].drag_ws):
        return NO_FIT
    if (found.drag_ws or 0.0) < reversal_step(sig):
        return NO_FIT
    return found


def reversal_step(sig: Signals) -> float:
    """The speed's change over one sample where it reverses (the median over the
    samples where the filtered speed changes sign), rad/s; 0 where it never reverses.

    A drag ``T_d·tanh(ω/ω_d)`` whose scale ``ω_d`` is below it rises from zero to its
    level between two samples at every reversal: as sampled, a jump at reversal, which
    is a dry friction's. It better simulates a friction under a speed loop only by the
    smoothing of the sign between samples (benchmark 318/103, a Coulomb friction under
    a speed PRBS: ``ω_d`` 1.69 rad/s against a step of 14 rad/s; 311/158: 2.1 against
    6.7), while each of 118 drags that won over a friction on the stored benchmark rows
    (eddy brakes, frictions along the travel, gear meshes) has a scale of 1.26 to 500
    times its run's step (docs/results/diagnose.md)."""
    w = sig.omega_f
    at = np.flatnonzero(np.signbit(w[1:]) != np.signbit(w[:-1]))
    if not len(at):
        return 0.0
    return float(np.median(np.abs(w[at + 1] - w[at])))


def without_friction(spec: ModelSpec) -> ModelSpec:
    """``spec`` without its dry friction (a Coulomb level and a Stribeck hump)."""
    return replace(spec, coulomb=False, stribeck_ws=None)


def competitor(bench: Bench, verdict: Scored, friction: str) -> Dragged | None:
    """The drag against a verdict ``verdict`` that names ``friction``, a dry friction
    (:attr:`~stand.effects.base.Effect.jumps_at_reversal`): a :class:`Dragged` where it
    simulates HOLDOUT significantly better and HOLDOUT's own search finds its speed
    scale (the friction dropped unless it simulates HOLDOUT significantly better beside
    the drag); else None."""
    base = without_friction(verdict.spec)
    spec = search(base, bench.train, bench.self_gaps(bench.train))
    if spec == NO_FIT:
        return None
    scored = bench.score(spec)
    test = speed_improvement(verdict, scored)
    if not test.significant(1):
        return None
    again = search(base, bench.holdout, bench.self_gaps(bench.holdout))
    ws, again_ws = spec.drag_ws or 0.0, again.drag_ws or 0.0
    if again == NO_FIT or not ratio_ok(ws, again_ws, SCALE_RATIO):
        return None
    both = bench.score(replace(verdict.spec, drag_ws=spec.drag_ws))
    kept = speed_improvement(scored, both).significant(1)
    return Dragged(scored=scored, without=verdict if kept else bench.score(base), test=test,
                   friction=friction, dropped=None if kept else friction, ws=ws,
                   holdout_ws=again_ws)


__all__ = ["BESIDE", "DROPPED", "Dragged", "competitor", "reversal_step", "scales", "search",
           "without_friction"]
