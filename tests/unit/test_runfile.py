"""CONTRACT §1: run files are read strictly, all or nothing, with messages that name the
file, the row and the column."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from stand.errors import InputError, RunFileError
from stand.runfile import MIN_SAMPLES, format_run, parse_run, read_run, write_run

HEADER = "time_s,current_A,position_rad"


def _rows(n: int = 25) -> list[str]:
    return [HEADER] + [f"{k * 0.001:.6f},{0.1 * k:.3f},{0.01 * k:.3f}" for k in range(n)]


def _write(tmp_path: Path, rows: list[str]) -> Path:
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def _refused(tmp_path: Path, rows: list[str]) -> str:
    path = _write(tmp_path, rows)
    with pytest.raises(RunFileError) as info:
        read_run(path, "single")
    message = str(info.value)
    assert str(path) in message       # names the file
    return message


def test_good_file_round_trips(tmp_path: Path) -> None:
    columns = {"time_s": np.arange(30) * 0.015, "current_A": np.linspace(0, 1, 30),
               "position_rad": np.linspace(0, 5, 30), "voltage_V": np.full(30, 12.0)}
    run = read_run(write_run(tmp_path / "ok.csv", columns), "single")
    assert len(run) == 30
    assert_allclose(run.dt_s, 0.015, rtol=1e-9)
    for name, values in columns.items():
        assert_allclose(run[name], values, rtol=1e-8)   # 9 significant digits written


def test_missing_column(tmp_path: Path) -> None:
    rows = _rows()
    rows[0] = "time_s,position_rad"
    message = _refused(tmp_path, rows)
    assert "current_A" in message and "row 1" in message


def test_non_numeric_cell(tmp_path: Path) -> None:
    rows = _rows()
    rows[5] = "0.004000,abc,0.040"           # file row 6 (header is row 1)
    message = _refused(tmp_path, rows)
    assert "row 6" in message and "current_A" in message and "'abc'" in message


@pytest.mark.parametrize("cell", ["nan", "NaN", "inf", "-inf"])
def test_nan_and_inf(tmp_path: Path, cell: str) -> None:
    rows = _rows()
    rows[8] = f"0.007000,0.700,{cell}"
    message = _refused(tmp_path, rows)
    assert "row 9" in message and "position_rad" in message and "finite" in message


def test_fewer_than_20_samples(tmp_path: Path) -> None:
    message = _refused(tmp_path, _rows(MIN_SAMPLES - 1))
    assert f"{MIN_SAMPLES - 1} samples" in message and "row" in message and "time_s" in message
    assert len(read_run(_write(tmp_path, _rows(MIN_SAMPLES)))) == MIN_SAMPLES


def test_non_increasing_time(tmp_path: Path) -> None:
    rows = _rows()
    rows[10] = "0.001000,1.0,1.0"            # row 11 goes back in time
    message = _refused(tmp_path, rows)
    assert "row 11" in message and "time_s" in message and "increas" in message


@pytest.mark.parametrize("time", ["0.011500", "0.010500"])
def test_non_uniform_period(tmp_path: Path, time: str) -> None:
    rows = _rows()
    rows[12] = f"{time},1.0,1.0"             # row 13: half a period early or late
    message = _refused(tmp_path, rows)
    assert "row 13" in message and "time_s" in message and "uniform" in message


def test_jitter_within_1_percent_is_accepted(tmp_path: Path) -> None:
    rows = _rows()
    rows[12] = "0.011005,1.0,1.0"            # 0.5 % of a period late: within tolerance
    assert len(read_run(_write(tmp_path, rows))) == 25


def test_unknown_extra_columns_are_ignored(tmp_path: Path) -> None:
    rows = [line + ",note" if k else line + ",operator_txt" for k, line in enumerate(_rows())]
    run = read_run(_write(tmp_path, rows))
    assert set(run.columns) == {"time_s", "current_A", "position_rad"}


def test_nothing_is_half_read() -> None:
    rows = _rows()
    rows[-1] = "0.024000,oops,0.240"         # the last row is bad: no run at all
    with pytest.raises(RunFileError, match="row 26"):
        parse_run("\n".join(rows), "single", "upload.csv")


def test_reducer_kind_needs_its_columns() -> None:
    text = format_run({"time_s": np.arange(25) * 1e-3, "current_in_A": np.zeros(25),
                       "position_in_rad": np.zeros(25)})
    with pytest.raises(RunFileError, match="current_out_A"):
        parse_run(text, "reducer", "stand.csv")


def test_run_file_errors_are_input_errors() -> None:
    assert issubclass(RunFileError, InputError) and issubclass(RunFileError, ValueError)
