"""The MAT/CSV importer: column mapping, expressions, clear errors, the `stand import` command."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy import io as sio

from stand.cli import main
from stand.errors import InputError
from stand.importer import evaluate, import_run, load_variables, map_columns, parse_mapping
from stand.runfile import read_run
from tests.conftest import REAL_DATA

N = 200
DT_S = 1e-3
#: format_run writes 9 significant digits; values read back agree to this relative tolerance.
CSV_RTOL = 1e-8


@pytest.fixture()
def signals() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(7)
    t = np.arange(N) * DT_S
    return {"t": t, "q": np.cumsum(rng.normal(size=N)) * 1e-3, "u": rng.normal(size=N)}


@pytest.fixture()
def mat_file(tmp_path: Path, signals: dict[str, np.ndarray]) -> Path:
    """A MAT file shaped like MATLAB saves: column vectors, 1x1 scalars, a 2-D table, a struct."""
    path = tmp_path / "rec.mat"
    table = np.column_stack([signals["t"], signals["q"], signals["u"]])
    sio.savemat(path, {
        "t": signals["t"][:, None], "qm": signals["q"][:, None], "vir": signals["u"][:, None],
        "gtau": np.array([[35.15]]), "data": table, "short": np.arange(N - 1.0)[:, None],
        "name": "EMPS", "bad": np.where(np.arange(N) == 17, np.nan, 1.0)[:, None],
        "s": {"pos": signals["q"][:, None], "gain": 2.0},
    })
    return path


def test_mat_mapping_with_scalar_factor_and_columns(mat_file: Path, signals: dict) -> None:
    run = import_run(mat_file, [("time_s", "t"), ("position_rad", "qm*1000"),
                                ("current_A", "vir*gtau")], "single")
    assert_array_equal(run.time_s, signals["t"])
    assert_allclose(run["position_rad"], signals["q"] * 1000, rtol=1e-15)
    assert_allclose(run["current_A"], signals["u"] * 35.15, rtol=1e-15)
    assert run.meta["mapping"]["current_A"] == "vir*gtau"


def test_table_columns_rows_struct_fields_and_signs(mat_file: Path, signals: dict) -> None:
    variables = load_variables(mat_file)
    assert_array_equal(evaluate("data[:,1]", variables, "f"), signals["q"])
    assert_array_equal(evaluate("data[:, -1]", variables, "f"), signals["u"])
    assert_allclose(evaluate("-data[:,2]/2", variables, "f"), -signals["u"] / 2, rtol=1e-15)
    assert_allclose(evaluate("s.pos*s.gain", variables, "f"), 2 * signals["q"], rtol=1e-15)
    assert_allclose(evaluate("qm*vir", variables, "f"), signals["q"] * signals["u"], rtol=1e-15)
    assert_allclose(evaluate("2.5e-3*vir", variables, "f"), 2.5e-3 * signals["u"], rtol=1e-15)
    row = evaluate("data[1,:]", {"data": np.arange(40.0).reshape(20, 2).T.copy()}, "f")
    assert_array_equal(row, np.arange(1.0, 40.0, 2))


@pytest.mark.parametrize(("expression", "words"), [
    ("qx", ["rec.mat", "'qx'", "gtau", "qm"]),                 # missing: lists what exists
    ("qm*short", ["short", f"{N - 1}", f"{N}"]),                 # lengths differ
    ("bad*vir", ["rec.mat", "bad*vir", "sample 17", "finite"]),  # non-finite
    ("data", ["data", f"({N}, 3)", "data[:,k]"]),                # 2-D without an index
    ("data[:,3]", ["data[:,3]", "out of range"]),
    ("data[:,x]", ["index 'x'"]),
    ("name", ["'name'", "not numeric"]),
    ("gtau*2", ["single number"]),
    ("qm*", ["empty factor"]),
])
def test_bad_expressions_name_the_file_and_variable(
        mat_file: Path, expression: str, words: list[str]) -> None:
    with pytest.raises(InputError) as caught:
        import_run(mat_file, [("time_s", "t"), ("position_rad", expression),
                              ("current_A", "vir")], "single")
    for word in words:
        assert word in str(caught.value), (word, str(caught.value))


def test_mapping_is_checked_against_the_run_kind(mat_file: Path) -> None:
    with pytest.raises(InputError, match="'voltage_in_V' is not a column of a single run"):
        import_run(mat_file, [("time_s", "t"), ("voltage_in_V", "vir")], "single")
    with pytest.raises(InputError, match="missing column.*current_A"):
        import_run(mat_file, [("time_s", "t"), ("position_rad", "qm")], "single")
    with pytest.raises(InputError, match=r"rec.mat: mapped columns differ in length \(time_s=t has "
                       rf"{N}, position_rad=short has {N - 1}, current_A=vir has {N} samples\)"):
        import_run(mat_file, [("time_s", "t"), ("position_rad", "short"), ("current_A", "vir")])
    with pytest.raises(InputError, match="mapped twice"):
        import_run(mat_file, [("time_s", "t"), ("time_s", "t")], "single")
    with pytest.raises(InputError, match="time_s must be strictly increasing"):
        import_run(mat_file, [("time_s", "-t"), ("position_rad", "qm"), ("current_A", "vir")])
    with pytest.raises(InputError, match="expected TARGET=SOURCE"):
        parse_mapping("current_A")


def test_step_and_reducer_kinds(mat_file: Path) -> None:
    step = import_run(mat_file, [("time_s", "t"), ("voltage_V", "vir"),
                                 ("velocity_rad_s", "qm")], "step")
    assert set(step.columns) == {"time_s", "voltage_V", "velocity_rad_s"}
    reducer = import_run(mat_file, [
        ("time_s", "t"), ("current_in_A", "vir"), ("position_in_rad", "qm"),
        ("current_out_A", "-vir"), ("position_out_rad", "qm/11")], "reducer")
    assert_allclose(reducer["position_out_rad"] * 11, reducer["position_in_rad"], rtol=1e-14)


def test_period_makes_time_when_time_is_not_mapped(signals: dict) -> None:
    run = map_columns({"x": signals["q"], "i": signals["u"]},
                      [("position_rad", "x"), ("current_A", "i")], "single", "mem", period_s=0.015)
    assert_allclose(run.dt_s, 0.015, rtol=1e-12)
    assert run.time_s[0] == 0.0


def test_csv_with_header_quoted_names_and_without_header(tmp_path: Path, signals: dict) -> None:
    table = np.column_stack([signals["t"], signals["q"], signals["u"]])
    with_header = tmp_path / "h.csv"
    np.savetxt(with_header, table, delimiter=";", fmt="%.17g",
               header="time;angle (deg);Motor current (mA)", comments="")
    run = import_run(with_header, [("time_s", "time"), ("position_rad", "'angle (deg)'*0.5"),
                                   ("current_A", '"Motor current (mA)"/1000')])
    assert_allclose(run["position_rad"], signals["q"] * 0.5, rtol=1e-15)
    assert_allclose(run["current_A"], signals["u"] / 1000, rtol=1e-15)
    bare = tmp_path / "bare.txt"
    np.savetxt(bare, table, fmt="%.17g")  # space separated, no header
    run = import_run(bare, [("time_s", "data[:,0]"), ("position_rad", "data[:,1]"),
                            ("current_A", "data[:,2]")])
    assert_array_equal(run["current_A"], signals["u"])
    broken = tmp_path / "broken.csv"
    broken.write_text("t,q,u\n0,1,2\n0.001,x,3\n")
    with pytest.raises(InputError, match=r"broken.csv: row 3, column 'q': 'x' is not a number"):
        load_variables(broken)


def test_unknown_suffix_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        load_variables(tmp_path / "nope.mat")
    (tmp_path / "x.xlsx").write_bytes(b"PK")
    with pytest.raises(InputError, match="unknown file type .xlsx"):
        load_variables(tmp_path / "x.xlsx")
    (tmp_path / "junk.mat").write_bytes(b"not a mat file at all" * 10)
    with pytest.raises(InputError, match="junk.mat"):
        load_variables(tmp_path / "junk.mat")


def test_cli_writes_a_run_file_and_reports_json(
        mat_file: Path, tmp_path: Path, signals: dict, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run.csv"
    code = main(["import", str(mat_file), "-o", str(out), "--json", "--map", "time_s=t",
                 "--map", "position_rad=data[:,1]", "--map", "current_A=vir*gtau"])
    assert code == 0
    result = json.loads(capsys.readouterr().out)
    assert result["samples"] == N and result["kind"] == "single"
    written = read_run(out, "single")
    assert_allclose(written["current_A"], signals["u"] * 35.15, rtol=CSV_RTOL)
    assert_allclose(written["position_rad"], signals["q"], rtol=CSV_RTOL, atol=1e-15)


def test_cli_bad_input_exits_2_and_writes_nothing(
        mat_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run.csv"
    code = main(["import", str(mat_file), "-o", str(out), "--map", "time_s=t",
                 "--map", "position_rad=qx", "--map", "current_A=vir"])
    captured = capsys.readouterr()
    assert code == 2
    assert "no variable 'qx'" in captured.err and captured.out == ""
    assert not out.exists()
    assert main(["import", str(mat_file), "--list", "--json"]) == 0
    listing = json.loads(capsys.readouterr().out)["variables"]
    assert listing["data"]["shape"] == [N, 3] and listing["gtau"]["shape"] == []


HSM150 = REAL_DATA / "hsm150" / "idf_neg_0.04_1.mat"


@pytest.mark.skipif(not HSM150.is_file(), reason=f"HSM150 real data not found at {HSM150}")
def test_real_table_file_maps_by_column_index() -> None:
    """HSM150: a 20000x7 table; the dataset README gives time, position and current columns."""
    run = import_run(HSM150, [("time_s", "data[:,0]"), ("position_rad", "data[:,2]"),
                              ("current_A", "data[:,6]")])
    assert len(run) == 20000
    assert_allclose(run.dt_s, 1e-3, rtol=1e-9)
    # Encoder of 2500 lines, 4x quadrature: every position is a multiple of 2π/10000 rad.
    counts = run["position_rad"] / (2 * np.pi / 10000)
    assert_allclose(counts, np.round(counts), atol=1e-6)
