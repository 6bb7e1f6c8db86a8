"""Shared fixtures of the integration tests.

``can_config``: the bus the bus tests run on — always python-can ``virtual`` (a fresh
channel per test, so tests never hear each other), plus ``socketcan`` on ``vcan0`` where
``/sys/class/net/vcan0`` exists (inside User-Mode Linux, see tests/vcan/run.sh).
"""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest

from bus.adapters import BusConfig

VCAN0 = Path("/sys/class/net/vcan0")
_channels = itertools.count()
CAN_CONFIGS = ["virtual"] + (["socketcan"] if VCAN0.exists() else [])


@pytest.fixture(params=CAN_CONFIGS)
def can_config(request: pytest.FixtureRequest) -> BusConfig:
    """A bus to run on: virtual (own channel) or socketcan vcan0."""
    if request.param == "socketcan":
        return BusConfig("socketcan", "vcan0")
    return BusConfig("virtual", f"test-bus-{next(_channels)}")
