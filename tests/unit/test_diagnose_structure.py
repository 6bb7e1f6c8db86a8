"""Structure beyond noise in what a model leaves (:mod:`stand.diagnosis.structure`):
the tests hold their level on noise alone, see a shape planted in both runs, and turn
a ``none`` or an "approximation" into ``unexplained`` when an effect outside the
vocabulary hides below the noise gap or behind a named effect.

The stand is that of :mod:`tests.unit.test_diagnose_effects` (Kt 0.05 N·m/A,
J 2e-5 kg·m², PRBS of ± 0.5 A, 1000-line encoder, 0.01 A current noise, 1 ms, 6 s).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from stand.diagnosis import diagnose
from stand.diagnosis.current_noise import CurrentNoise
from stand.diagnosis.noise import UNEXPLAINED_FACTOR, unexplained
from stand.diagnosis.signals import Signals, prepare
from stand.diagnosis.significance import FAMILY_ALPHA, MIN_SHRINK
from stand.diagnosis.simulate import segments
from stand.diagnosis.structure import (
    COUPLED_SHAPES,
    DRIFT_SHAPES,
    FAMILIES,
    SHAPES,
    _Leak,
    _predictor,
    _taken,
    along_travel_test,
    shapes_test,
    structure_test,
)
from stand.effects import UNEXPLAINED
from stand.errors import InputError
from stand.runfile import Run
from tests.bench.diagnose.benchmark import case_runs, draw_case, simulate_case
from tests.unit.test_diagnose_effects import MOTOR, PLANTED, stand_runs

#: Fan drag coefficient, N·m·s²/rad²: 0.25 mN·m at 100 rad/s, a hundredth of the drive
#: torque; the re-identified D/J takes most of it and the gap stays within the noise gap.
WEAK_FAN_CD = 2.5e-8


@pytest.fixture(scope="module")
def runs() -> tuple[Signals, Signals, np.ndarray]:
    train, holdout = stand_runs({})
    tr, ho = prepare(train), prepare(holdout)
    return tr, ho, segments(len(ho), ho.dt_s, 0.1, 20).index


def _coloured(rng: np.random.Generator, n: int, rho: float = 0.8) -> np.ndarray:
    """AR(1) noise of unit innovation, correlation ``rho`` from sample to sample."""
    white = rng.normal(size=n)
    out = np.empty(n)
    out[0] = white[0]
    for k in range(1, n):
        out[k] = rho * out[k - 1] + white[k]
    return out


def _planted(runs: tuple[Signals, Signals, np.ndarray], seed: int,
             torque: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
             ) -> tuple[np.ndarray, np.ndarray]:
    """Equation errors of TRAIN and HOLDOUT: ``torque(w, i, t)`` of each run's speed and
    low-passed current in TRAIN's RMS scales and its time from −0.5 to 0.5, plus AR(1)
    noise (:func:`_coloured`, drawn from ``seed``, TRAIN's first)."""
    tr, ho, _ = runs
    rng = np.random.default_rng(seed)
    omega_rms, current_rms = np.sqrt(np.mean(tr.omega_f**2)), np.sqrt(np.mean(tr.current**2))

    def one(sig: Signals) -> np.ndarray:
        t = np.linspace(-0.5, 0.5, len(sig))
        shape = torque(sig.omega_f / omega_rms, sig.filt(sig.current) / current_rms, t)
        return shape + _coloured(rng, len(sig))

    e_tr = one(tr)
    return e_tr, one(ho)


def test_noise_alone_holds_the_level(runs: tuple[Signals, Signals, np.ndarray]) -> None:
    tr, ho, index = runs
    rng = np.random.default_rng(5)
    draws = 40
    flagged = [0, 0, 0]
    for _ in range(draws):
        e_tr, e_ho = _coloured(rng, len(tr)), _coloured(rng, len(ho))
        flagged[0] += structure_test(e_tr, tr, e_ho, ho, index).significant
        flagged[1] += along_travel_test(e_tr, tr, e_ho, ho, index).significant
        flagged[2] += shapes_test(e_tr, tr, e_ho, ho, index).significant
    # level FAMILY_ALPHA = 1 %: 4 or more of 40 has a chance of 0.08 % under the null
    assert FAMILY_ALPHA == 0.01
    assert max(flagged) <= 3, flagged


def test_a_speed_squared_torque_in_both_runs_is_structure(
        runs: tuple[Signals, Signals, np.ndarray]) -> None:
    tr, ho, index = runs
    e_tr, e_ho = _planted(runs, 6, lambda w, i, t: 2.0 * w * np.abs(w))
    result = structure_test(e_tr, tr, e_ho, ho, index)
    assert result.significant, result.test


def test_a_drag_that_drifts_over_the_run_is_structure_of_its_own_family(
        runs: tuple[Signals, Signals, np.ndarray]) -> None:
    tr, ho, index = runs
    # a viscous drag falling by half over each run, its mean taken by the model's D
    e_tr, e_ho = _planted(runs, 8, lambda w, i, t: -4.0 * w * t)
    drift = structure_test(e_tr, tr, e_ho, ho, index, DRIFT_SHAPES).test
    both = shapes_test(e_tr, tr, e_ho, ho, index)
    assert both.significant and both.test.p_value == pytest.approx(
        min(1.0, len(FAMILIES) * drift.p_value))
    # the first family alone does not see it
    assert not structure_test(e_tr, tr, e_ho, ho, index).significant


def test_a_torque_constant_falling_with_the_speed_is_structure_of_the_coupled_family(
        runs: tuple[Signals, Signals, np.ndarray]) -> None:
    tr, ho, index = runs
    # field weakening: a loss Kt·γ·|ω|/ω_ref·i, its mean share taken by the model's Kt
    e_tr, e_ho = _planted(runs, 9, lambda w, i, t: 3.0 * i * np.abs(w))
    coupled = structure_test(e_tr, tr, e_ho, ho, index, COUPLED_SHAPES).test
    both = shapes_test(e_tr, tr, e_ho, ho, index)
    assert both.significant and both.test.p_value == pytest.approx(
        min(1.0, len(FAMILIES) * coupled.p_value))
    # neither of the other families sees it
    assert not structure_test(e_tr, tr, e_ho, ho, index).significant
    assert not structure_test(e_tr, tr, e_ho, ho, index, DRIFT_SHAPES).significant


def test_shapes_of_two_families_are_refused_as_one_test(
        runs: tuple[Signals, Signals, np.ndarray]) -> None:
    tr, ho, index = runs
    e = np.zeros(len(tr))
    with pytest.raises(InputError, match="subset of one of"):
        structure_test(e, tr, e, ho, index, ("omega_cubed", "i_abs_omega"))


def test_a_torque_along_the_travel_is_found_at_an_order_below_one(
        runs: tuple[Signals, Signals, np.ndarray]) -> None:
    tr, ho, index = runs
    rng = np.random.default_rng(7)

    def planted(sig: Signals) -> np.ndarray:
        return (0.5 * np.sign(sig.omega_f) * np.sin(sig.theta_f / 4.3)
                + _coloured(rng, len(sig)))

    assert along_travel_test(planted(tr), tr, planted(ho), ho, index).significant


def test_unknown_shapes_are_refused(runs: tuple[Signals, Signals, np.ndarray]) -> None:
    tr, ho, index = runs
    with pytest.raises(InputError, match="shapes"):
        structure_test(np.zeros(len(tr)), tr, np.zeros(len(ho)), ho, index, ("omega_fifth",))
    assert "omega_abs_omega" in SHAPES


def test_the_rule_reads_the_shape_where_the_size_cannot_decide() -> None:
    noise = 0.2
    along = {"along_shrink": MIN_SHRINK}
    # within the noise factor: the shape decides
    assert not unexplained(0.5, 0.5, noise)
    assert unexplained(0.5, 0.5, noise, p_shapes=0.004)
    assert unexplained(0.5, 0.5, noise, p_along=0.004, **along)
    # the level is shared by the two tests
    assert not unexplained(0.5, 0.5, noise, p_shapes=0.006, p_along=0.006, **along)
    # a remainder taken as the named effect's approximation is not, when it varies along
    # the travel (at the level it shares with the speed and the drift shapes' tests
    # after named effects)
    assert not unexplained(10.0, 1.0, noise, named=True)
    assert unexplained(10.0, 1.0, noise, p_along=0.003, named=True, **along)
    assert not unexplained(10.0, 1.0, noise, p_along=0.004, named=True, **along)
    # ... and shrinks HOLDOUT's equation error as much as a candidate effect must
    for named in (False, True):
        assert not unexplained(10.0 if named else 0.5, 0.5, noise, p_along=1e-60, named=named,
                               along_shrink=0.9 * MIN_SHRINK)
    # after a named effect the joint speed-current-time shapes do not count (the
    # vocabulary's own models leave them: sticking, a rigid contact), within the noise
    # or beyond it
    assert not unexplained(10.0, 1.0, noise, p_shapes=1e-9, named=True)
    assert not unexplained(10.0, 0.5, noise, p_shapes=1e-9, named=True)
    assert unexplained(10.0, 0.5, noise, p_along=0.003, named=True, **along)


def test_a_fan_drag_near_the_noise_gap_is_unexplained_not_none() -> None:
    def fan(theta: float, omega: float, i: float, t: float) -> float:
        return WEAK_FAN_CD * omega * abs(omega)

    result = diagnose(*stand_runs({}, extra_torque=fan), kt=MOTOR.Kt)
    assert result.noise_gap_percent is not None
    # the size alone says noise (within UNEXPLAINED_FACTOR times the noise gap, beyond
    # the noise gap itself, within which no shape counts) ...
    assert (result.noise_gap_percent < result.gap_percent
            <= UNEXPLAINED_FACTOR * result.noise_gap_percent)
    # ... the shape does not
    assert result.verdict == UNEXPLAINED, result.message
    assert any("shape no noise makes" in note for note in result.notes)


def test_a_friction_level_that_changes_along_the_travel_is_not_coulombs_approximation() -> None:
    tc = PLANTED["coulomb_friction"]["Tc"]

    def tight_spot(theta: float, omega: float, i: float, t: float) -> float:
        # a third of the friction level, varying with 1/3.7 cycles per revolution
        return tc * 0.3 * math.sin(theta / 3.7 + 1.0) * math.tanh(omega)

    result = diagnose(*stand_runs({"coulomb_friction": PLANTED["coulomb_friction"]},
                                  extra_torque=tight_spot), kt=MOTOR.Kt)
    assert result.verdict == f"coulomb_friction+{UNEXPLAINED}", result.message
    assert result.position_structure_p_value is not None
    assert result.position_structure_p_value < FAMILY_ALPHA


def test_the_share_a_candidate_takes_equals_least_squares_also_on_collinear_columns() -> None:
    """The order search's shortcut through the 4 × 4 Gram matrix gives what a least-squares
    solve on the samples gives, also when ``sign(ω)·sin`` and ``sin`` coincide (a run
    that never reverses), where the Gram matrix is singular."""
    rng = np.random.default_rng(5)
    theta = np.cumsum(rng.standard_normal(5000)) * 0.05
    left = rng.standard_normal(5000)
    for sign in (np.sign(rng.standard_normal(5000)), np.ones(5000)):
        sin, cos = np.sin(0.3 * theta), np.cos(0.3 * theta)
        x = np.column_stack([sign * sin, sign * cos, sin, cos])
        coef = np.linalg.lstsq(x, left, rcond=None)[0]
        assert _taken(x, left) == pytest.approx(float(left @ (x @ coef)), rel=1e-9)


def test_the_corrected_fit_takes_the_current_noise_out_of_a_gain() -> None:
    # errors in variables: y = 2·s read through x = s + n. Least squares gives the gain
    # times var(s)/(var(s) + σ²); the corrected fit, told σ², gives the gain.
    rng = np.random.default_rng(4)
    n = 20_000
    signal = np.sin(np.linspace(0.0, 60.0, n))
    sigma = 0.5  # var(s) = 0.5, σ² = 0.25: the plain gain is 2·0.5/0.75
    x = np.column_stack([signal + sigma * rng.normal(size=n), np.ones(n)])
    y = 2.0 * signal
    noise = CurrentNoise(variance=sigma**2, moments=np.array([[0.0, 0.0], [0.0, 1.0]]),
                         gain=0.0, column=np.zeros(n))
    leak = _Leak(noise, np.zeros((n, 2)), np.array([1.0, 0.0]), np.ones(n))
    plain, corrected = _predictor(x, y), _predictor(x, y, leak)
    assert plain[0] == pytest.approx(4.0 / 3.0, rel=0.03)
    assert corrected[0] == pytest.approx(2.0, rel=0.03)


@pytest.mark.xfail(strict=True, reason=(
    "known false alarm (issue-21-prior): plain least squares reads the current's shapes "
    "on these effect-free sines (p 0.0026 and 7e-10), and the corrected fit, started from "
    "the model, now agrees; what passed them before was the corrected fit dropping part "
    "of the model's current term (shrink -1.12 and -0.11), which hid a saturating torque "
    "constant as well"))
@pytest.mark.parametrize("index", [34, 69])
def test_an_effect_free_current_sine_read_with_noise_is_none(index: int) -> None:
    # benchmark seed 252: current-mode sines on effect-free stands, the current read to
    # 1/40 (case 34) and 1/190 (case 69) of its RMS. Least squares on the noisy current
    # attenuated the current's gain and let the current's shapes take up the rest, on
    # TRAIN and HOLDOUT alike: both were `unexplained` (structure p 0.003 and 7e-10).
    _, train, holdout = case_runs(index, 252)
    result = diagnose(train, holdout)
    assert result.verdict == "none", result.message
    assert result.structure_p_value >= FAMILY_ALPHA


def test_a_corrected_fit_must_be_borne_out_by_plain_least_squares() -> None:
    # case 9 of seed 271: an effect-free current-mode sine of 2.9 Hz. On one frequency the
    # columns span little more than two directions; the fit corrected for the current's
    # noise read structure on HOLDOUT (p 8e-57, shrink 0.17) that plain least squares
    # does not see (p 1), and the verdict was `unexplained`
    _, train, holdout = case_runs(9, 271)
    result = diagnose(train, holdout)
    assert result.verdict == "none", result.notes
    assert result.structure_p_value > FAMILY_ALPHA


def test_a_corrected_fit_keeps_its_start_along_the_directions_it_leaves_out() -> None:
    # y = 3·a, read through columns a and a + ε·b that barely span two directions: the
    # corrected fit leaves the second direction out; started from the coefficients
    # (3, 0) it keeps them there, where from zero it splits the gain between the two
    # columns and predicts another run, on which b is not small, far off
    rng = np.random.default_rng(7)
    n = 5000
    a, b = np.sin(np.linspace(0.0, 40.0, n)), rng.normal(size=n)
    x = np.column_stack([a, a + 1e-3 * b])
    noise = CurrentNoise(variance=1e-12, moments=np.array([[0.0, 0.0], [0.0, 1.0]]),
                         gain=0.0, column=np.zeros(n))
    leak = _Leak(noise, np.zeros((n, 2)), np.array([1.0, 0.0]), np.ones(n))
    y = 3.0 * a
    started = _predictor(x, y, leak, np.array([3.0, 0.0]))
    np.testing.assert_allclose(started, [3.0, 0.0], atol=1e-6)
    from_zero = _predictor(x, y, leak)
    assert abs(from_zero[1]) > 1.0  # the gain split along the direction left out


@pytest.mark.parametrize("index", [42, 342])
def test_a_saturating_torque_constant_under_a_current_command_is_unexplained(index: int) -> None:
    # benchmark seed 260 (tuning outside set): a torque constant falling with the current
    # (Kt·i·(1 − α·x²/(1 + x²)), α 0.07 and 0.04) under a current sine (case 42) and a
    # PRBS (case 342). Plain least squares reads the shapes i|i| and i³ on HOLDOUT (p
    # 7e-53 and 1e-55); the fit corrected for the current's noise, re-taking the model's
    # current term from zero, dropped part of it along directions it left out, predicted
    # HOLDOUT worse than its null (p 1), and both verdicts were `none`
    case = draw_case(index, 260, outside_share=0.3, outside_set="tuning")
    assert list(case.outside) == ["kt_saturation"]
    train, holdout = (Run(simulate_case(case, k), name)
                      for k, name in enumerate(("train", "holdout")))
    result = diagnose(train, holdout)
    assert result.verdict == UNEXPLAINED, result.message
    assert result.structure_p_value < FAMILY_ALPHA / 2


def test_a_drag_thinning_over_the_run_within_the_noise_is_unexplained() -> None:
    # benchmark seed 291 (outside set UNSEEN), case 47: a lubricant's drag falling by 47 %
    # over each run, under a current sine, the gap 2.1 times the noise gap: the re-
    # identified D takes its mean, and the first family of shapes sees nothing (p 1); the
    # verdict was `none`. The drift shapes read it (p 8e-73 with the period-mean current)
    case, train, holdout = case_runs(47, 291, outside_set="unseen", current_mean=True)
    assert list(case.outside) == ["warming_drag"]
    result = diagnose(train, holdout)
    assert result.verdict == UNEXPLAINED, result.message
    assert result.gap_percent < UNEXPLAINED_FACTOR * result.noise_gap_percent
    assert result.structure_p_value < FAMILY_ALPHA / 2


def test_the_drift_shapes_count_only_with_a_candidates_shrink() -> None:
    # benchmark seed 290 case 64: an effect-free current sine of 2.9 Hz. The drift shapes
    # take a little of the nominal model's own error over the run (p 5e-8, shrink 0.012),
    # below the least shrink a candidate effect needs: the verdict stays `none`
    case, train, holdout = case_runs(64, 290, current_mean=True)
    assert not case.effects and not case.outside
    result = diagnose(train, holdout)
    assert result.verdict == "none", result.notes


@pytest.mark.parametrize(("seed", "index"), [(308, 64), (309, 164)])
def test_a_friction_level_along_a_long_travel_is_found_between_the_orders_searched(
        seed: int, index: int) -> None:
    # Held-out benchmark cases of a dry friction whose level changes along the travel at
    # 1/5.6 and 1/5.4 cycles per revolution, under a current noise command that turns the
    # shaft 420 and 382 revolutions on TRAIN. The orders searched there (at most
    # MAX_TRAVEL_ORDERS, up to MAX_TRAVEL_ORDER) lay four steps of the travel apart, and
    # the nearest was off by up to half a cycle over the travel: the test took nothing
    # (p 0.48 and 1) and the verdict was `coulomb_friction`. Searched again at the
    # travel's own step around the best, the level is found.
    case, train, holdout = case_runs(index, seed, held_out=True, current_mean=True)
    assert list(case.outside) == ["position_friction"]
    result = diagnose(train, holdout)
    assert result.verdict == f"coulomb_friction+{UNEXPLAINED}", result.message
    assert result.position_structure_p_value is not None
    assert result.position_structure_p_value < FAMILY_ALPHA
    assert result.position_structure_shrink is not None
    assert result.position_structure_shrink >= MIN_SHRINK

