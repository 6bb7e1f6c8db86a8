"""``stand serve [--host H] [--port P]``: the HTTP service (CONTRACT §4) under uvicorn.

Without ``STAND_API_KEY`` the service binds to loopback only, says so, and refuses any
other address (exit 2).
"""

from __future__ import annotations

import argparse
import logging
from typing import Any

from stand.cli import options
from stand.datadir import DataDirLock
from stand.errors import InputError
from stand.settings import get_settings

log = logging.getLogger("stand.serve")


def is_loopback(host: str) -> bool:
    """Whether ``host`` names only the loopback interface."""
    from api.origin import is_loopback_name

    return is_loopback_name(host)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--host", help="address to bind (default: setting STAND_HOST, 127.0.0.1)")
    parser.add_argument("--port", type=options.port, help="TCP port (default: setting STAND_PORT, 8000)")
    parser.add_argument("--log-level", default="info",
                        choices=["critical", "error", "warning", "info", "debug"])


def run(args: argparse.Namespace) -> dict[str, Any]:
    import uvicorn

    from api.app import create_app

    settings = get_settings()
    host = args.host or settings.host
    port = settings.port if args.port is None else args.port
    if not 0 <= port <= 65535:
        raise InputError(f"--port must be in 0..65535, got {port}")
    if settings.api_key is None:
        if not is_loopback(host):
            raise InputError(
                f"--host {host}: refusing to listen beyond loopback without a key; set "
                "STAND_API_KEY (mutating routes then need 'Authorization: Bearer <key>') "
                "or bind 127.0.0.1")
        log.warning("no STAND_API_KEY set: listening on loopback %s only, mutating routes "
                    "are open to local callers", host)
    log.info("database %s", settings.database)
    # The lock before uvicorn: a second service on this data directory exits here,
    # naming the owner's PID, without touching the first one's runs.
    with DataDirLock(settings.data_dir) as lock:
        uvicorn.run(create_app(settings, lock=lock), host=host, port=port,
                    log_level=args.log_level)
    return {"host": host, "port": port, "stopped": True}


def summarize(result: dict[str, Any]) -> str:
    return f"service on {result['host']}:{result['port']} stopped"
