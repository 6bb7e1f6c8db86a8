"""Ctrl-C during ``stand run`` (issue 20, item 7): the partial run is kept, the message says
the drives were quick-stopped, and the trace ends with the quick-stop frames."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import can

from bus import cia402
from bus.adapters import BusConfig

REPO = Path(__file__).resolve().parents[2]
#: The motor's drive: node 1, RPDO1 on 0x201 carrying the controlword first.
RPDO1 = 0x201
#: Long enough that Ctrl-C always comes mid-run, s of stand time.
DURATION_S = 60
#: Time the whole command may take once interrupted, s.
EXIT_TIMEOUT_S = 60


def _as_at_a_terminal() -> None:
    """Ctrl-C as at a terminal: a suite started in the background by a shell without job
    control (``bash tests/run.sh &`` in a script) ignores SIGINT, and its children
    inherit that: the run never saw the signal and ended at 100 %."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_keeps_the_partial_run_and_ends_the_trace_with_the_stop(
        can_config: BusConfig, tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "stand", "run", "seed000_no_load", "-o", str(tmp_path),
         "--duration", str(DURATION_S), "--interface", can_config.interface,
         "--channel", can_config.channel, "--simulate"],
        cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=_as_at_a_terminal)
    assert proc.stderr is not None
    lines = []
    for line in proc.stderr:  # progress goes to stderr in 5 % steps; wait for the first one
        lines.append(line)
        if "%" in line and not line.rstrip().endswith(" 0 %"):
            break
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=EXIT_TIMEOUT_S)
    err = "".join(lines) + err
    assert proc.returncode == 1, err
    assert "interrupted (Ctrl-C): drives quick-stopped" in err and "samples so far kept" in err, err

    rows = (tmp_path / "no_load_1.csv").read_text().splitlines()
    assert rows[0].startswith("time_s") and 0 < len(rows) - 1 < DURATION_S * 1000
    rpdos = [msg for msg in can.LogReader(str(tmp_path / "no_load_1.log")) if msg.arbitration_id == RPDO1]
    controlwords = [int.from_bytes(msg.data[:2], "little") for msg in rpdos]
    stops = len(controlwords) - controlwords.index(cia402.CW_QUICK_STOP)
    # Every RPDO from the first quick stop on is a quick stop, and the trace ends with them.
    assert stops >= 1 and set(controlwords[-stops:]) == {cia402.CW_QUICK_STOP}
    assert set(controlwords[:-stops]) == {cia402.CW_ENABLE_OPERATION}
