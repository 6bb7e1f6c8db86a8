"""The top-level options of ``stand``: --version, -v/-q log levels, and GET /profiles' EDS."""

from __future__ import annotations

import logging
from importlib.metadata import version

import pytest

from stand.cli import main
from stand.profiles import list_profiles


def test_version_is_the_installed_package_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"stand {version('motorstand')}"


@pytest.mark.parametrize(("flags", "level"), [([], logging.INFO), (["-q"], logging.WARNING),
                                              (["-qq"], logging.ERROR), (["-v"], logging.DEBUG),
                                              (["-v", "-q"], logging.INFO)])
def test_verbosity_sets_the_log_level(flags: list[str], level: int, tmp_path: object) -> None:
    assert main([*flags, "import", "/nonexistent/run.csv", "-o", "x.csv"]) == 2  # bad input
    assert logging.getLogger("stand").level == level


def test_a_command_is_required_after_options(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["-v"])
    assert stop.value.code == 2 and "give a command" in capsys.readouterr().err


def test_profiles_list_the_eds() -> None:
    profiles = list_profiles()
    assert profiles["eds"] == ["motorstand_cia402.eds", "motorstand_io401.eds"]
    assert "crouzet_82800502_eol" in profiles["limits"]
