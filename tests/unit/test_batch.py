"""Batches on the serial path: inputs, options, rows, fleets, tables, stored runs."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

import stand
from stand.batch import run_batch
from stand.batch.inputs import expand_inputs
from stand.batch.operations import OPERATIONS, check_options
from stand.batch.table import write_table
from stand.cli import main
from stand.errors import InputError, NotFoundError
from stand.storage import Storage
from tests.batch_runs import write_bad, write_runs


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two folders (two fleets): 4 Crouzet runs with a bad file, 3 small iron-core runs."""
    root = tmp_path_factory.mktemp("fleet")
    write_runs(root / "crouzet", 4, "crouzet_82800502")
    write_bad(root / "crouzet" / "run_bad.csv")
    write_runs(root / "ironcore", 3, "small_ironcore_19v", seed0=10)
    return root


def test_inputs_expand_globs_in_sorted_order_with_the_folder_as_group(fleet: Path) -> None:
    items = expand_inputs([str(fleet / "*" / "*.csv")], 1)
    assert [Path(i.refs[0]).name for i in items] == sorted(
        p.name for p in (fleet / "crouzet").glob("*.csv")) + [f"run_{k:03d}.csv" for k in (10, 11, 12)]
    assert [i.index for i in items] == list(range(8))
    assert [i.group for i in items] == ["crouzet"] * 5 + ["ironcore"] * 3
    assert {i.group for i in expand_inputs([str(fleet / "*" / "*.csv")], 1, pool="all")} == {"all"}
    by_name = expand_inputs([str(fleet / "*" / "*.csv")], 1, pool=r"re:run_(\d\d)\d")
    assert [i.group for i in by_name] == ["00"] * 4 + ["(unknown)"] + ["01"] * 3


def test_pairs_match_two_globs_one_to_one(fleet: Path) -> None:
    pair = f"{fleet}/crouzet/run_00[01].csv,{fleet}/crouzet/run_00[23].csv"
    items = expand_inputs([pair], 2)
    assert [[Path(r).name for r in i.refs] for i in items] == [
        ["run_000.csv", "run_002.csv"], ["run_001.csv", "run_003.csv"]]
    with pytest.raises(InputError, match=r"two sides must match as many runs, got 2 .* and 3"):
        expand_inputs([f"{fleet}/crouzet/run_00[01].csv,{fleet}/ironcore/*.csv"], 2)
    with pytest.raises(InputError, match="FIRST,SECOND"):
        expand_inputs([f"{fleet}/crouzet/run_000.csv"], 2)


def test_bad_inputs_and_options_are_refused_before_any_item_runs(fleet: Path) -> None:
    with pytest.raises(InputError, match="matches no file"):
        expand_inputs([str(fleet / "nothing*.csv")], 1)
    with pytest.raises(InputError, match="not a file"):
        expand_inputs([str(fleet / "missing.csv")], 1)
    with pytest.raises(InputError, match="database"):
        expand_inputs(["run:abc"], 1)
    with pytest.raises(InputError, match="capture group"):
        expand_inputs([str(fleet / "*" / "*.csv")], 1, pool="re:run")
    with pytest.raises(InputError, match="unknown option.*ratio"):
        check_options(OPERATIONS["identify"], {"ratio": 11})
    with pytest.raises(InputError, match="option added_inertia is required"):
        check_options(OPERATIONS["torque-constant"], {})
    with pytest.raises(InputError, match="k_in must be a finite number > 0"):
        check_options(OPERATIONS["efficiency"], {"ratio": 11, "k_in": -1, "k_out": 1})
    with pytest.raises(InputError, match="method must be one of default, paper"):
        check_options(OPERATIONS["identify"], {"method": "euler"})
    with pytest.raises(InputError, match="operation must be one of"):
        run_batch("fit", [str(fleet / "*" / "*.csv")], workers=0)


def test_rows_are_the_commands_json_and_a_bad_file_is_one_error_row(fleet: Path) -> None:
    result = run_batch("identify", [str(fleet / "*" / "*.csv")], workers=0)
    assert (result.items, result.errors) == (8, 1)
    bad = result.rows[4]
    assert bad["input"].endswith("run_bad.csv") and bad["Kt_over_J"] is None
    assert bad["error"].startswith("RunFileError:") and "row 2, column position_rad" in bad["error"]
    first = stand.identify(stand.read_run(fleet / "crouzet" / "run_000.csv")).to_json()
    row = result.rows[0]
    assert row["error"] == ""
    for name, value in first.items():  # the same call: the same numbers, bit for bit
        assert row[name] == (json.dumps(value) if isinstance(value, (list, dict)) else value), name


def test_pooled_sums_of_one_run_give_that_runs_estimate(fleet: Path) -> None:
    # The sums the batch rebuilds are the ones stand.identify solved: pooling a single
    # run must give its own estimate, to rounding (the same sums, solved the same way).
    path = fleet / "crouzet" / "run_001.csv"
    result = run_batch("identify", [str(path)], workers=0)
    # Pooling is of seed 000's sums: compare seed 000's model (effects none). Its standard
    # errors are the block sandwich there and white-noise ones in the pool, so not compared.
    single = stand.identify(stand.read_run(path), effects="none")
    pooled = result.fleets[0].pooled
    assert pooled is not None and pooled["samples"] == single.samples
    for name in ("Kt_over_J", "D_over_J", "C_over_J", "fit_percent"):
        assert_allclose(pooled[name], getattr(single, name), rtol=1e-12, err_msg=name)
    assert result.fleets[0].std is None and "two results" in result.fleets[0].message


def test_fleets_pool_each_folder_and_bracket_the_profiles_kt_over_j(fleet: Path) -> None:
    result = run_batch("identify", [str(fleet / "*" / "*.csv")], workers=0)
    fleets = {f.group: f for f in result.fleets}
    assert (fleets["crouzet"].runs, fleets["crouzet"].errors) == (4, 1)
    for group, profile in (("crouzet", "crouzet_82800502"), ("ironcore", "small_ironcore_19v")):
        motor = stand.load_motor(profile).motor
        truth = motor.Kt / motor.J
        f = fleets[group]
        values = [r["Kt_over_J"] for r in result.rows if r["group"] == group and not r["error"]]
        assert_allclose(f.mean, np.mean(values), rtol=1e-12)
        assert_allclose(f.std, np.std(values, ddof=1), rtol=1e-12)
        assert f.std_ci95[0] < f.std < f.std_ci95[1]
        assert f.mean_ci95[0] < f.mean < f.mean_ci95[1]
        # Same motor, half-second runs: the fleet estimate lands within 10 % of the
        # profile's (the equation-error fit of a short filtered run is biased by a few %,
        # docs/results/core.md); a sum of the wrong runs or rows would miss by far more.
        assert abs(f.pooled["Kt_over_J"] / truth - 1) < 0.10, (group, f.pooled, truth)


def test_tables_read_back_to_the_same_rows(fleet: Path, tmp_path: Path) -> None:
    result = run_batch("identify", [str(fleet / "*" / "*.csv")], workers=0)
    out = write_table(tmp_path / "r.csv", result.rows)
    with out.open(encoding="utf-8") as handle:
        back = list(csv.DictReader(handle))
    assert list(back[0]) == list(result.rows[0])
    for row, read in zip(result.rows, back, strict=True):
        assert float(read["Kt_over_J"] or "nan") == (row["Kt_over_J"] or float("nan")) or row["error"]
        assert read["error"] == row["error"] and read["A"] == (row["A"] or "")
    pq = pytest.importorskip("pyarrow.parquet")
    table = pq.read_table(write_table(tmp_path / "r.parquet", result.rows)).to_pylist()
    assert table == result.rows
    with pytest.raises(InputError, match="must end in .csv or .parquet"):
        write_table(tmp_path / "r.xlsx", result.rows)


def test_stored_runs_by_id_and_by_query(fleet: Path, tmp_path: Path) -> None:
    db = tmp_path / "stand.sqlite3"
    storage = Storage(db)
    paths = sorted((fleet / "ironcore").glob("*.csv"))
    ids = [storage.store_run(stand.read_run(p), "single").id for p in paths]
    storage.close()
    by_query = run_batch("identify", ["query:kind=single,state=done"], workers=0, database=db)
    by_id = run_batch("identify", [f"run:{i}" for i in ids], workers=0, database=db)
    by_file = run_batch("identify", [str(p) for p in paths], workers=0)
    assert [r["input"] for r in by_query.rows] == [f"run:{i}" for i in ids]  # oldest first
    for a, b, c in zip(by_query.rows, by_id.rows, by_file.rows, strict=True):
        assert a["Kt_over_J"] == b["Kt_over_J"]
        assert_allclose(a["Kt_over_J"], c["Kt_over_J"], rtol=1e-6)  # CSV keeps 9 digits
    assert by_query.fleets[0].group == "(unknown)"  # uploads carry no profile
    with pytest.raises(NotFoundError):
        run_batch("identify", ["run:nope"], workers=0, database=db)
    with pytest.raises(InputError, match="no stored run matches"):
        run_batch("identify", ["query:kind=reducer"], workers=0, database=db)
    with pytest.raises(InputError, match="KEY=VALUE with KEY one of"):
        run_batch("identify", ["query:colour=red"], workers=0, database=db)


def test_the_command_writes_the_table_and_the_fleets(fleet: Path, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "results.csv"
    code = main(["batch", "identify", str(fleet / "*" / "*.csv"), "-o", str(out),
                 "--workers", "0", "--json"])
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    assert "batch: 8/8 items" in captured.err  # the progress bar, on stderr only
    assert code == 0 and (summary["items"], summary["errors"]) == (8, 1)
    assert summary["output"] == str(out) and out.exists()
    fleets = json.loads(Path(summary["fleets_output"]).read_text())
    assert [f["group"] for f in fleets] == ["crouzet", "ironcore"]
    assert main(["batch", "identify", str(fleet / "*.csv"), "-o", str(out), "--workers", "0"]) == 2
    assert "matches no file" in capsys.readouterr().err
    assert main(["batch", "efficiency", str(fleet / "*" / "*.csv"), "-o", str(out),
                 "--workers", "0"]) == 2
    assert "option ratio is required" in capsys.readouterr().err
    for bad, said in ((["--workers", "-1"], "--workers"), (["--chunk", "0"], "--chunk"),
                      (["-o", str(tmp_path / "r.xlsx")], ".csv, .parquet")):
        args = ["batch", "identify", str(fleet / "*" / "*.csv"), "-o", str(out), *bad]
        assert main(args) == 2 and said in capsys.readouterr().err
