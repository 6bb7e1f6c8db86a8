"""Every ``stand`` option is checked when the line is parsed: exit 2 and a message that
names the option, never a traceback (CONTRACT §2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stand.cli import main
from stand.runfile import format_run

MOTOR = "crouzet_82800502"
STAND = "cycloidal_two_motor"


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("cli")
    rng = np.random.default_rng(0)
    n = 2000
    good = folder / "run.csv"
    good.write_text(format_run({"time_s": np.arange(n) * 1e-3, "current_A": rng.standard_normal(n),
                                "position_rad": np.cumsum(rng.standard_normal(n))}))
    tiny = folder / "tiny_step.csv"
    tiny.write_text(format_run({"time_s": np.arange(n) * 1e-300,
                                "current_A": rng.standard_normal(n),
                                "position_rad": np.cumsum(rng.standard_normal(n))}))
    empty_mat = folder / "empty.mat"
    empty_mat.write_bytes(b"")
    huge = folder / "huge.csv"
    huge.write_text("time_s,current_A\n" + "1" * 2_000_000 + "\n")
    return {"run": good, "tiny": tiny, "mat": empty_mat, "huge": huge, "dir": folder}


def exit_code(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as stop:
        return int(stop.code or 0)


CASES = [
    # (argv with {run} {dir} ... placeholders, option named in the message)
    ("simulate {motor} -o {dir}/x.csv --duration nan", "--duration"),
    ("simulate {motor} -o {dir}/x.csv --duration inf", "--duration"),
    ("simulate {motor} -o {dir}/x.csv --period nan", "--period"),
    ("simulate {motor} -o {dir}/x.csv --period 1e-300", "--period"),
    ("simulate {stand} -o {dir}/x.csv --period -0.001", "--period"),
    ("simulate {motor} -o {dir}/x.csv --duration 3600 --period 1e-5", "--period"),
    ("simulate {motor} -o {dir}/x.csv --level nan", "--level"),
    ("simulate {motor} -o {dir}/x.csv --added-inertia nan", "--added-inertia"),
    ("simulate {motor} -o {dir}/x.csv --added-inertia -1", "--added-inertia"),
    ("simulate {motor} -o {dir}/x.csv --seed -1", "--seed"),
    ("simulate {motor} -o /proc/x.csv", "--output"),
    ("simulate {motor} -o {dir}", "--output"),
    ("simulate {motor} -o {dir}/x.csv --effect cogging:Tcog=0.01,N=1.5", "--effect"),
    ("simulate {motor} -o {dir}/x.csv --effect delay:k=1e9", "--effect"),
    ("torque-constant --no-load {run} --loaded {run} --added-inertia -1", "--added-inertia"),
    ("torque-constant --no-load {run} --loaded {run} --added-inertia nan", "--added-inertia"),
    ("identify {run} --no-load-current nan", "--no-load-current"),
    ("identify /dev/zero", "run"),
    ("identify {tiny}", "time_s"),
    ("efficiency {run} --ratio nan --k-in 1 --k-out 1", "--ratio"),
    ("step-identify {run} --plot /etc/hostname", "--plot"),
    ("step-identify {run} --plot /proc/x.png", "--plot"),
    ("diagnose {run} --holdout {run} --horizon nan", "--horizon"),
    ("diagnose {run} --holdout {run} --plot /etc/hostname", "--plot"),
    ("diagnose {run} --holdout {run} --max-effects 0", "--max-effects"),
    ("import {huge} --bandwidth nan", "--bandwidth"),
    ("import {mat} -o {dir}/o.csv --map time_s=t", "empty.mat"),
    ("import {huge} -o {dir}/o.csv --map current_A=current_A", "huge.csv"),
    ("import {run} -o /proc/o.csv --map current_A=current_A", "--output"),
    ("run seed000_no_load -o /proc/x", "--output"),
    ("run seed000_no_load -o {dir}/r --seed -1", "--seed"),
    ("run seed000_no_load -o {dir}/r --duration nan", "--duration"),
    ("serve --port 70000", "--port"),
]


@pytest.mark.parametrize(("line", "named"), CASES, ids=[c[0].split(" -")[0] + f"[{c[1]}]"
                                                       for c in CASES])
def test_bad_option_exits_2_naming_it(files: dict[str, Path], line: str, named: str,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    argv = line.format(motor=MOTOR, stand=STAND, **{k: str(v) for k, v in files.items()}).split()
    assert exit_code(argv) == 2
    err = capsys.readouterr().err
    assert named in err and "Traceback" not in err


def test_nothing_written_by_refused_output_checks(files: dict[str, Path]) -> None:
    before = sorted(p.name for p in files["dir"].iterdir())
    exit_code(f"simulate {MOTOR} -o {files['dir']}/x.csv --duration nan".split())
    assert sorted(p.name for p in files["dir"].iterdir()) == before
