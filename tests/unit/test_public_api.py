"""The package root is the front door: every public name resolves, results print as the CLI."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

import stand
import stand.diagnosis.engine  # the subpackage loaded first must not shadow stand.diagnose
from stand.cli import main
from stand.runfile import write_run

README = Path(__file__).resolve().parents[2] / "README.md"


def test_every_public_name_resolves_and_the_operations_are_functions() -> None:
    for name in stand.__all__:
        assert getattr(stand, name) is not None, name
    from stand import diagnose, efficiency, identify, read_run, torque_constant

    for function in (diagnose, efficiency, identify, read_run, torque_constant,
                     stand.step_identify, stand.simulate, stand.load_motor, stand.load_stand):
        assert callable(function) and not isinstance(function, type(stand)), function
    assert issubclass(stand.RunFileError, stand.StandError)


def test_an_unknown_name_is_an_attribute_error() -> None:
    with pytest.raises(AttributeError, match="no attribute 'identfy'"):
        _ = stand.identfy  # type: ignore[attr-defined]


@pytest.mark.parametrize("command", ["identify", "diagnose"])
def test_to_json_is_exactly_what_the_command_line_prints(
        command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    runs = [stand.simulate("crouzet_82800502", 4.0, period_s=2e-3, mode="current", level=0.0,
                           amplitude=0.3, seed=seed) for seed in (1, 2)]
    paths = [str(write_run(tmp_path / f"run{k}.csv", run.columns)) for k, run in enumerate(runs)]
    read = [stand.read_run(path) for path in paths]
    if command == "identify":
        expected = stand.identify(read[0]).to_json()
        argv = ["identify", paths[0], "--json"]
    else:
        expected = stand.diagnose(read[0], read[1]).to_json()
        argv = ["diagnose", paths[0], "--holdout", paths[1], "--json"]
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out) == expected


def test_the_readme_example_runs(capsys: pytest.CaptureFixture[str]) -> None:
    section = README.read_text(encoding="utf-8").split("## Python API", 1)[1]
    match = re.search(r"```python\n(.*?)```", section, re.S)
    assert match, "README's Python API section has no python block"
    namespace: dict[str, object] = {}
    exec(compile(match.group(1), "README.md", "exec"), namespace)  # noqa: S102
    result, truth = namespace["result"], namespace["truth"]
    # 1 kHz, 5 s of the profile's speed loop with 10 mA current noise: Kt/J within 3 %
    assert abs(result.Kt_over_J / truth - 1) < 0.03  # type: ignore[attr-defined]
    assert "Kt/J =" in capsys.readouterr().out
