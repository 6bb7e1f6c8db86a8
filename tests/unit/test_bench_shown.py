"""The benchmark draws an outside effect, and each effect of a pair, again until it shows
against the case's twin runs without it (``draw_case(until_shown=True)``, the bench's
``--until-shown``): an effect the re-identified nominal model takes up leaves no gap
beyond noise, and ``none`` is then the right answer. Simulation and the oracle only; no
diagnosis runs here."""

from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path

from tests.bench.diagnose.benchmark import Case, _shows, _torque_ref, _visible_each, draw_case


def _draw(index: int, seed: int, until_shown: bool) -> Case:
    return draw_case(index, seed, outside_share=0.3, outside_set="held_out",
                     current_mean=True, until_shown=until_shown)


def test_an_elastic_load_the_nominal_model_takes_up_is_drawn_again() -> None:
    # seed 315, case 31: an elastic load under a current-loop sine, SNR 5.7 against the
    # true plant, but Kt/J re-identified on TRAIN takes it up: diagnosed `none`, and
    # counted an outside miss by the draw before stop 67
    first = _draw(31, 315, until_shown=False)
    assert (first.truth, first.kind, first.draws, first.shown) == (
        ["outside:elastic_load"], "sine", 1, None)
    with tempfile.TemporaryDirectory() as folder:
        assert _visible_each(first, None, Path(folder), 10.0, current_mean=True) == {
            "elastic_load": False}
    case = _draw(31, 315, until_shown=True)
    assert case.truth == ["outside:elastic_load"]
    assert case.draws > first.draws
    assert case.shown == {"elastic_load": True}


def test_a_pair_is_drawn_again_until_both_its_effects_show() -> None:
    # seed 315, case 54: cogging with a backlash under a PRBS; on its first draw the
    # cogging adds nothing that shows beside the backlash (diagnosed `backlash`)
    first = _draw(54, 315, until_shown=False)
    assert (first.truth, first.draws) == (["cogging", "backlash"], 1)
    with tempfile.TemporaryDirectory() as folder:
        assert _visible_each(first, None, Path(folder), 10.0, current_mean=True) == {
            "cogging": False, "backlash": True}
    case = _draw(54, 315, until_shown=True)
    assert case.draws > first.draws
    assert case.shown == {"cogging": True, "backlash": True}


def test_a_case_whose_effect_shows_at_once_is_the_same_draw_either_way() -> None:
    # seed 315, case 10: an elastic load under a sine that does show against its twin
    first = _draw(10, 315, until_shown=False)
    case = _draw(10, 315, until_shown=True)
    assert case.shown == {"elastic_load": True}
    assert dataclasses.replace(case, shown=None) == first


def test_a_single_vocabulary_effect_is_not_checked() -> None:
    # the oracle's "visible" judges a single effect; its draw is the SNR's alone
    case = draw_case(4, 260, until_shown=True)
    assert (len(case.effects), case.shown) == (1, None)
    assert case == draw_case(4, 260)


def test_a_draw_that_holds_the_shaft_still_is_drawn_again() -> None:
    # seed 310, case 90 (a Stribeck friction with a backlash): its 7th and 8th draws
    # stuck the shaft on TRAIN ("position_rad never changes"), which ended the benchmark
    # run; here a Coulomb friction fifty times the drive's torque on case 91's stand
    case = _draw(91, 310, until_shown=False)
    stuck = dataclasses.replace(case, effects={
        **case.effects, "coulomb_friction": {"Tc": 50 * _torque_ref(case)}})
    assert not _shows(10.0, current_mean=True)(stuck)
    assert stuck.shown == {"coulomb_friction": False, "backlash": False}
