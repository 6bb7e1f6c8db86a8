"""Result objects of a diagnosis (CONTRACT §3 field names)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from stand.jsonable import JsonResult


@dataclass(frozen=True)
class EffectScore:
    """One candidate effect scored on HOLDOUT.

    Attributes
    ----------
    effect : str
        Vocabulary name.
    gap_percent : float
        Holdout gap with the effect added to the nominal model and re-identified on
        TRAIN, %.
    shrink : float
        ``1 − gap_percent / nominal gap``.
    significant : bool
        The improvement over the nominal model passes the noise-aware test.
    params : dict
        Fitted parameters in physical units (see :func:`stand.diagnosis.candidates.params`).
    p_value : float
        One-sided p-value of the improvement.
    consistent : bool
        The same search on HOLDOUT finds the same effect (order, delay, similar size).
    """

    effect: str
    gap_percent: float
    shrink: float
    significant: bool
    params: dict[str, float | int | None]
    p_value: float
    consistent: bool


@dataclass(frozen=True)
class SelectionStep:
    """One effect added to the verdict, tested against the model before it.

    The table of :class:`EffectScore` scores each effect alone against the nominal
    model; an effect added after others is in the verdict because of its test as an
    addition to them, which this records.

    Attributes
    ----------
    effect : str
        Vocabulary name.
    after : list of str
        The verdict's effects before it (empty for the first, tested against the nominal
        model: its row of the table).
    gap_before_percent, gap_percent : float
        Holdout gap of the model before and with it, %.
    shrink : float
        ``1 − gap_percent / gap_before_percent``.
    p_value : float
        One-sided p-value of the improvement, corrected for the candidates of its step.
    """

    effect: str
    after: list[str]
    gap_before_percent: float
    gap_percent: float
    shrink: float
    p_value: float


@dataclass(frozen=True)
class Where:
    """Where the gap lies.

    Attributes
    ----------
    regime : str
        ``low_speed``, ``reversal``, ``high_speed``, ``acceleration``, ``steady`` or
        ``everywhere``.
    cycles_per_rev : int or None
        Order of a position-periodic residual, cycles per revolution.
    band_hz : list of float or None
        ``[low, high]`` band holding most of the residual energy, Hz.
    lag_s : float or None
        Lag of the strongest residual–current cross-correlation, s (positive: the
        residual follows the current).
    regime_energy : dict of str to float
        Mean squared residual in each regime over the overall mean.
    velocity_sign_energy : dict of str to float
        The same for ``positive`` and ``negative`` velocity.
    current_level_energy : dict of str to float
        The same for ``low``, ``middle`` and ``high`` thirds of ``|current|`` (a
        residual growing with the current points at the torque constant).
    """

    regime: str
    cycles_per_rev: int | None = None
    band_hz: list[float] | None = None
    lag_s: float | None = None
    regime_energy: dict[str, float] = field(default_factory=dict)
    velocity_sign_energy: dict[str, float] = field(default_factory=dict)
    current_level_energy: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Diagnosis(JsonResult):
    """The sim-to-real gap of a HOLDOUT run, where it lies and which effect explains it.

    Attributes
    ----------
    gap_percent : float
        Holdout gap of the nominal model, %.
    where : Where
        Where it lies.
    effects : list of EffectScore
        Every candidate of the vocabulary, best (smallest gap) first.
    verdict : str
        The effect (or ``+``-joined effects, best first) that explains the gap, ending in
        ``unexplained`` when a gap beyond noise remains after them; ``none`` when the
        nominal gap is within noise.
    verdict_gap_percent : float
        Holdout gap of the model with the verdict's effects, %.
    verdict_params : dict
        Parameters of each effect of the verdict, fitted together.
    nominal : dict
        The nominal model identified on TRAIN (``Kt_over_J`` 1/(A·s²)... per J).
    anchoring : dict
        How the simulation is re-anchored (``horizon_s``, ``segments``).
    noise_floor_percent : float
        Gap that encoder quantization alone gives (velocity difference noise), %.
    message : str
        One line for people.
    notes : list of str
        What the data cannot tell apart or resolve (e.g. Coulomb friction from a current
        offset when the shaft never reverses), and the experiment that would.
    steps : list of SelectionStep
        How the verdict was built: each of its effects with its test as an addition to
        the ones before it.
    plots : list of str
        The figures written by the command line's ``--plot``, if any.
    residual_where : Where
        Where what remains after the verdict's effects lies (the equation error of the
        model with them on HOLDOUT), as ``where``.
    model : dict
        The nominal parameters re-identified with the verdict's effects (``Kt_over_J``
        1/(A·s²), ``D_over_J`` 1/s, ...) and each effect's parameters under its name.
    noise_gap_percent : float
        Gap that noise alone gives (quantization and current noise through the free
        run), %; a gap above ``UNEXPLAINED_FACTOR`` times it is beyond noise.
    structure_p_value : float or None
        p-value of the test for structure beyond noise in what the verdict's effects
        leave (:func:`stand.diagnosis.structure.shapes_test`): shapes no vocabulary
        effect makes, fitted on TRAIN, predicting HOLDOUT's equation error (three
        families, the smallest p-value tripled).
    position_structure_p_value : float or None
        The same test with the position shapes alone (a dry friction whose level changes
        along the travel).
    position_structure_shrink : float or None
        Its shrink of HOLDOUT's equation error; below the diagnosis' least shrink that
        counts (``MIN_SHRINK``) its structure does not count.
    speed_structure_p_value, speed_structure_shrink : float or None
        After named effects: the test with the speed shapes alone, beside a dry friction
        level (a torque that grows with the speed other than a level and a slope), on the
        samples where the current changes least, its p-value and its shrink of HOLDOUT's
        equation error there; None with nothing named.
    drift_structure_p_value, drift_structure_shrink : float or None
        After named effects: the drift shapes' own test (a viscous drag and a dry
        friction level changing over the run), its p-value (1 below the least shrink
        that counts) and its shrink of HOLDOUT's equation error; None with nothing named.
    replayed_noise_gap_percent : float or None
        With nothing named and a nominal gap between the noise gap and
        ``UNEXPLAINED_FACTOR`` times it: the gap noise leaves on replays of HOLDOUT, the
        nominal model's own motion read through the run's encoder and current noise
        (:mod:`stand.diagnosis.noise_replay`), %; a nominal gap above ``REPLAY_FACTOR``
        times it (``SPEED_LOOP_REPLAY_FACTOR`` under a speed loop) is beyond noise. None
        elsewhere, and where the run holds a speed target that is not one tone.
    """

    gap_percent: float
    where: Where
    effects: list[EffectScore]
    verdict: str
    verdict_gap_percent: float
    verdict_params: dict[str, dict[str, float | int | None]]
    nominal: dict[str, float]
    anchoring: dict[str, float | int | str]
    noise_floor_percent: float
    message: str = ""
    notes: list[str] = field(default_factory=list)
    steps: list[SelectionStep] = field(default_factory=list)
    plots: list[str] = field(default_factory=list)
    residual_where: Where | None = None
    model: dict[str, object] = field(default_factory=dict)
    noise_gap_percent: float | None = None
    structure_p_value: float | None = None
    position_structure_p_value: float | None = None
    position_structure_shrink: float | None = None
    speed_structure_p_value: float | None = None
    speed_structure_shrink: float | None = None
    drift_structure_p_value: float | None = None
    drift_structure_shrink: float | None = None
    replayed_noise_gap_percent: float | None = None


@dataclass(frozen=True)
class Traces:
    """What the figures show, on the HOLDOUT samples covered by the segments.

    Attributes
    ----------
    time_s : ndarray
        Sample times, s, shape (segments, horizon).
    measured, nominal, verdict : ndarray
        Measured speed, the nominal model's and the verdict model's simulated speed, rad/s.
    theta, omega : ndarray
        Filtered position (rad) and velocity (rad/s) of HOLDOUT, full length.
    residual : ndarray
        Equation error of the nominal model on HOLDOUT, rad/s², full length.
    dt_s : float
        Sample period, s.
    """

    time_s: np.ndarray
    measured: np.ndarray
    nominal: np.ndarray
    verdict: np.ndarray
    theta: np.ndarray
    omega: np.ndarray
    residual: np.ndarray
    dt_s: float
