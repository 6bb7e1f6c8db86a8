"""Files as labs bring them: MDF 4 out and back in, scope exports (decimal comma, units row,
preamble), functions and pi in --map, and the warning on an implausible sample rate."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from stand.cli import main
from stand.delimited import TableFormat
from stand.errors import InputError
from stand.importer import evaluate, import_run
from stand.mdf import read_mdf, unit_of, write_mdf
from stand.runfile import read_run, write_run
from stand.sources import ReadOptions

N = 400


@pytest.fixture()
def run_csv(tmp_path: Path) -> Path:
    rng = np.random.default_rng(3)
    t = np.arange(N) * 1e-3
    return write_run(tmp_path / "run.csv", {
        "time_s": t, "current_A": rng.normal(size=N), "position_rad": np.cumsum(rng.normal(size=N)),
        "velocity_rad_s": rng.normal(size=N) * 100, "voltage_V": rng.normal(size=N) * 12})


def test_csv_to_mf4_to_csv_is_equal(run_csv: Path, tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    mf4, back = tmp_path / "run.mf4", tmp_path / "back.csv"
    assert main(["export", str(run_csv), "-o", str(mf4), "--motor", "crouzet_82800502",
                 "--seed", "11", "--meta", "operator=kim"]) == 0
    assert main(["import", str(mf4), "-o", str(back), "--json"]) == 0
    result = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert result["file_meta"] == {"source": str(run_csv), "kind": "single",
                                   "motor": "crouzet_82800502", "seed": "11", "operator": "kim"}
    original, returned = read_run(run_csv), read_run(back)
    assert list(returned.columns) == list(original.columns)
    for name in original.columns:
        assert_array_equal(returned[name], original[name], err_msg=name)


def test_mf4_channels_carry_units(run_csv: Path, tmp_path: Path) -> None:
    run = read_run(run_csv)
    write_mdf(tmp_path / "u.mf4", run.columns, {"note": "a <b> & c"})
    from asammdf import MDF

    with MDF(tmp_path / "u.mf4") as mdf:
        units = {name: mdf.get(name).unit for name in run.columns if name != "time_s"}
    assert units == {"current_A": "A", "position_rad": "rad", "velocity_rad_s": "rad/s",
                     "voltage_V": "V"}
    assert read_mdf(tmp_path / "u.mf4")[1] == {"note": "a <b> & c"}
    assert unit_of("position_out_rad") == "rad" and unit_of("current_in_A") == "A"


def test_a_scope_export_reads_with_decimal_comma_and_units_row(tmp_path: Path) -> None:
    t = np.arange(60) * 0.5  # ms
    angle = np.linspace(0, 720, 60)  # degrees
    current = np.sin(t)
    lines = ["Scope XYZ export", "Channels: 3", "t;angle;I", "ms;deg;A"]
    lines += [f"{a:.6f};{b:.6f};{c:.6f}".replace(".", ",") for a, b, c in zip(t, angle, current, strict=True)]
    path = tmp_path / "scope.csv"
    path.write_text("\n".join(lines) + "\n")
    options = ReadOptions(TableFormat(decimal=",", skip_rows=2))
    run = import_run(path, [("time_s", "t/1000"), ("position_rad", "angle*pi/180"),
                            ("current_A", "I")], options=options)
    assert_allclose(run.time_s, t / 1000, rtol=1e-12)
    assert_allclose(run["position_rad"], np.deg2rad(angle), rtol=1e-6)
    assert run.meta["notes"] == ["line 4 read as a units row: ms, deg, A"]
    assert run.meta["warnings"] == []
    with pytest.raises(InputError, match=r"row 5, column 't'.*give --decimal ,"):
        import_run(path, [("time_s", "t")], options=ReadOptions(TableFormat(skip_rows=2)))


def test_time_in_ms_read_as_s_is_warned(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                        caplog: pytest.LogCaptureFixture) -> None:
    path = tmp_path / "ms.csv"
    t_ms = np.arange(100) * 1.0
    path.write_text("t,q,i\n" + "".join(f"{a},{a * 0.01},{math.sin(a)}\n" for a in t_ms))
    assert main(["import", str(path), "-o", str(tmp_path / "out.csv"), "--json",
                 "--map", "time_s=t", "--map", "position_rad=q", "--map", "current_A=i"]) == 0
    captured = capsys.readouterr()
    warnings = json.loads(captured.out)["warnings"]
    assert len(warnings) == 1 and "1 Hz" in warnings[0] and "t/1000" in warnings[0]
    assert any("implausible" in r.getMessage() and r.levelname == "WARNING" for r in caplog.records)
    fixed = import_run(path, [("time_s", "t/1000"), ("position_rad", "q"), ("current_A", "i")])
    assert fixed.meta["warnings"] == []


def test_functions_and_pi_in_expressions() -> None:
    x = np.linspace(-1, 1, 50)
    variables = {"x": x, "deg": np.linspace(0, 180, 50), "k": np.array([4.0])}
    assert_allclose(evaluate("sqrt(x*x)", variables, "f"), np.abs(x), rtol=1e-15)
    assert_allclose(evaluate("-deg2rad(deg)*k", variables, "f"), -np.deg2rad(variables["deg"]) * 4,
                    rtol=1e-15)
    assert_allclose(evaluate("deg*pi/180", variables, "f"), np.deg2rad(variables["deg"]), rtol=1e-15)
    assert_allclose(evaluate("sin(x*pi)/2", variables, "f"), np.sin(x * np.pi) / 2, rtol=1e-15)
    with pytest.raises(InputError, match="unknown function 'sinh'"):
        evaluate("sinh(x)", variables, "f")
    with pytest.raises(InputError, match="not finite at sample 0"):
        evaluate("log(x)", variables, "f")


def test_bad_table_options_name_the_parameter() -> None:
    with pytest.raises(InputError, match="decimal must be"):
        TableFormat(decimal=";")
    with pytest.raises(InputError, match="skip_rows must be >= 0"):
        TableFormat(skip_rows=-1)
