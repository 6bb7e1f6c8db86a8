"""Reports: end-of-line limits decide PASS and FAIL as written, bad limit profiles are named,
and ``stand report`` embeds every figure in one HTML file that needs nothing else."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from stand.cli import main
from stand.errors import NotFoundError, ProfileError
from stand.figures import effects_figure
from stand.report import Bound, LimitsProfile, check_limits, load_limits, operation_of
from stand.runfile import write_run

LIMITS = LimitsProfile(name="eol", limits={"Kt": Bound(min=0.05, max=0.055),
                                           "efficiency": Bound(min=0.75)})


@pytest.mark.parametrize(("kt", "efficiency", "passed"), [
    (0.0527, 0.80, [True, True]),
    (0.0499, 0.80, [False, True]),   # just under min
    (0.0549, 0.749, [True, False]),  # efficiency just under min
    (0.0550, 0.75, [True, True]),    # bounds are inclusive
])
def test_limits_pass_and_fail_at_their_bounds(kt: float, efficiency: float, passed: list[bool]) -> None:
    results = [("torque constant", {"Kt": kt}), ("efficiency", {"efficiency": efficiency})]
    assert [c.passed for c in check_limits(results, LIMITS)] == passed


def test_a_limit_nothing_measured_fails_and_params_count() -> None:
    checks = check_limits([("step", {"params": {"Kt": 0.052}})], LIMITS)
    assert [(c.field, c.value, c.passed, c.source) for c in checks] == [
        ("Kt", 0.052, True, "step"), ("efficiency", None, False, "not measured")]


def test_bad_limits_profiles_are_named(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nlimits:\n  Kt: {min: 2, max: 1}\n")
    with pytest.raises(ProfileError, match=r"bad.yaml: limits.Kt: .*min 2.0 > max 1.0"):
        load_limits(bad)
    bad.write_text("name: x\nlimits:\n  Kt: {}\n")
    with pytest.raises(ProfileError, match="give min, max or both"):
        load_limits(bad)
    with pytest.raises(NotFoundError, match="crouzet_82800502_eol"):
        load_limits("no_such_limits")
    assert load_limits("crouzet_82800502_eol").limits["Kt"].min == pytest.approx(0.0501)


def test_stand_report_embeds_figures_and_checks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "session"
    t = np.arange(300) * 1e-3
    write_run(folder / "no_load.csv", {"time_s": t, "current_A": np.sin(30 * t),
                                       "position_rad": t * 20, "velocity_rad_s": 20 + 0 * t})
    (folder / "tc.json").write_text(json.dumps(
        {"Kt": 0.0524, "Kt_std": 2e-4, "Kt_ci95": [0.052, 0.0528], "J": 1.2e-5, "D": 1e-6,
         "C": 0.0, "repeats": 5, "no_load_current_A": 0.06, "warnings": ["a <warning>"]}))
    (folder / "speed.png").write_bytes(effects_figure(
        {"gap_percent": 5.0, "verdict": "cogging",
         "effects": [{"effect": "cogging", "gap_percent": 1.0, "shrink": 0.8, "significant": True}]}))
    out = tmp_path / "report.html"
    assert main(["report", str(folder), "-o", str(out), "--limits", "crouzet_82800502_eol",
                 "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["passed"] is True and result["figures"] == 2
    page = out.read_text()
    assert len(re.findall(r"<img [^>]*src='data:image/png;base64,", page)) == 2
    assert "http" not in page.replace("motorstand", "")  # nothing fetched from anywhere
    assert "0.052 … 0.0528" in page and "N·m/A" in page and "a &lt;warning&gt;" in page
    assert operation_of(json.loads((folder / "tc.json").read_text())) == "torque-constant"
