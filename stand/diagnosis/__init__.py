"""Sim-to-real gap diagnosis (issue 5, CONTRACT §3).

``diagnose(train, holdout)`` identifies the nominal model of seed 000 on TRAIN, measures
its gap on HOLDOUT, says where it lies, scores every effect of the vocabulary as a model
extension, and names the one (or the few) that explain the gap, or ``none``.

Modules: :mod:`.signals` (derived signals), :mod:`.model` (regressors and Q-matrix fit),
:mod:`.simulate` (re-anchored free run), :mod:`.candidates` (effects as extensions, by
name), :mod:`.significance` (noise-aware test), :mod:`.where` (residual analysis),
:mod:`.engine` (the procedure), :mod:`.report` (result objects), :mod:`.plots`
(figures). Each effect's model, search and checks live in :mod:`stand.effects`; the blind
benchmark on simulated stands lives outside the package, in ``tests/bench/diagnose/``.
"""

from stand.diagnosis.engine import diagnose
from stand.diagnosis.report import Diagnosis, EffectScore, SelectionStep, Where

__all__ = ["Diagnosis", "EffectScore", "SelectionStep", "Where", "diagnose"]
