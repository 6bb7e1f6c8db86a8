"""``stand step-identify`` (CONTRACT §2): JSON fields, --known, --method, --plot, exit codes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from stand.cli import main
from stand.runfile import write_run
from stand.stepid import PARAM_NAMES
from stand.stepid.simulated import simulate_step_run


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("step")
    with_current = simulate_step_run("ms150_dcm150f", [8.5], 4.0, seed=41)
    speed_only = simulate_step_run("ms150_dcm150f", [8.5, 0.0] * 3, 9.0, seed=42,
                                   with_current=False)
    return {"current": write_run(folder / "current.csv", with_current.columns),
            "speed": write_run(folder / "speed.csv", speed_only.columns)}


def run_cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(["step-identify", *args])
    out, err = capsys.readouterr()
    return code, out, err


def test_json_has_the_contract_fields(files: dict[str, Path],
                                      capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli([str(files["current"]), "--json"], capsys)
    assert code == 0
    result = json.loads(out)
    tf = result["transfer_function"]
    assert len(tf["num"]) == 1 and len(tf["den"]) == 3 and tf["den"][0] == 1
    assert set(result["params"]) == set(PARAM_NAMES)
    assert result["identifiable"] == list(PARAM_NAMES)
    assert all(isinstance(result["params"][n], float) for n in PARAM_NAMES)
    assert 90 < result["fit_percent"] <= 100
    assert set(result["whiteness"]) == {"velocity_rad_s", "current_A"}
    assert isinstance(result["whiteness"]["velocity_rad_s"]["passed"], bool)


def test_speed_only_gives_nulls_and_known_values_come_back_as_given(
        files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli([str(files["speed"]), "--json"], capsys)
    result = json.loads(out)
    assert code == 0 and result["identifiable"] == []
    assert all(result["params"][n] is None for n in PARAM_NAMES)
    code, out, _ = run_cli([str(files["speed"]), "--json", "--known", "R=2.937",
                            "--known", "K=0.6571", "--method", "lm"], capsys)
    result = json.loads(out)
    assert code == 0 and result["method"] == "lm"
    assert result["params"]["R"] == 2.937 and result["params"]["K"] == 0.6571
    assert sorted(result["identifiable"]) == ["J", "Kf", "L"]
    assert result["params"]["J"] == pytest.approx(0.064744, rel=0.03)


def test_human_summary_and_plot(files: dict[str, Path], tmp_path: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    png = tmp_path / "fit.png"
    code, out, _ = run_cli([str(files["current"]), "--plot", str(png)], capsys)
    assert code == 0
    assert "ω(s)/v(s)" in out and "residual whiteness" in out and "95 %" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("args, message", [
    (["--known", "Q=1"], "NAME one of"),
    (["--known", "R=abc"], "not a number"),
    (["--known", "R=-2"], "> 0"),
])
def test_bad_known_exits_2(files: dict[str, Path], capsys: pytest.CaptureFixture[str],
                           args: list[str], message: str) -> None:
    code, out, err = run_cli([str(files["speed"]), *args], capsys)
    assert code == 2 and out == "" and message in err


def test_missing_column_exits_2_naming_the_file(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,voltage_V\n" + "".join(f"{k * 0.001},1\n" for k in range(30)))
    code, _, err = run_cli([str(bad)], capsys)
    assert code == 2 and "bad.csv" in err and "velocity_rad_s" in err
