"""The curl scripts of examples/ run a whole lab session against a real uvicorn."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.integration.test_api_support import ROOT, serve

#: Wall-time bound of the whole session on 2 shared cores, s.
SESSION_TIMEOUT_S = 240


@pytest.mark.skipif(shutil.which("curl") is None, reason="the examples need curl")
def test_examples_lab_session(tmp_path: Path) -> None:
    with serve(tmp_path / "server", api_key="example-key") as server:
        env = {**os.environ, "BASE_URL": server.base_url, "API_KEY": "example-key",
               "STATE_DIR": str(tmp_path / "state"), "REPEATS": "2", "DURATION_S": "3"}
        done = subprocess.run(["bash", str(ROOT / "examples" / "session.sh")], env=env,
                              capture_output=True, text=True, timeout=SESSION_TIMEOUT_S)
        assert done.returncode == 0, f"stdout:\n{done.stdout}\nstderr:\n{done.stderr}"
        kt = float(re.search(r"Kt = ([0-9.]+)", done.stdout).group(1))  # type: ignore[union-attr]
        eta = float(re.search(r"efficiency = ([0-9.]+)", done.stdout).group(1))  # type: ignore[union-attr]
        # 3 %: the tolerance of the lab-session test (2 short repeats, 10 mA current noise).
        assert kt == pytest.approx(0.0527, rel=0.03)  # crouzet_82800502
        assert eta == pytest.approx(0.80, rel=0.03)  # cycloidal_two_motor
        assert "== 06_diagnosis" in done.stdout and "node 1" in done.stdout
        # The reversing diagnosis profile turns the shaft both ways: the Crouzet motor's
        # Coulomb friction is named, not aliased with a current offset.
        diagnosis = done.stdout.split("== 06_diagnosis", 1)[1].split("== bus", 1)[0]
        verdict = re.search(r"verdict: ([a-z_+]+)", diagnosis)
        assert verdict is not None, diagnosis
        assert verdict.group(1).split("+")[0] == "coulomb_friction", diagnosis
        assert "cannot be told apart" not in diagnosis, diagnosis
        # Without the key the same scripts are refused.
        env["API_KEY"] = ""
        refused = subprocess.run(["bash", str(ROOT / "examples" / "stop.sh")], env=env,
                                 capture_output=True, text=True, timeout=60)
        assert refused.returncode != 0 and "HTTP 401" in refused.stderr
