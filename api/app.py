"""The FastAPI application: storage and the stand are opened in the lifespan.

``create_app()`` builds the app from :func:`stand.settings.get_settings`; tests pass their
own settings, storage or stand runner. At start-up the app takes the data directory's
lock (:class:`stand.datadir.DataDirLock`; a second service on it refuses to start, naming
the owner's PID), then marks runs a dead predecessor left live as ``aborted`` and prunes
uploads past ``STAND_UPLOAD_RETENTION_S``.
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI

from api import errors, pages
from api.limits import BodyLimit
from api.origin import LoopbackOnly
from api.routers import analysis, batch, health, profiles, results, runs, stand
from api.uploads import parse_lanes
from stand.datadir import DataDirLock
from stand.jobs import JobManager
from stand.runner import SIMULATED_MASTER_OPTIONS, ControllerRunner, StandRunner
from stand.settings import Settings, get_settings
from stand.storage import Storage

log = logging.getLogger("stand.api")

DESCRIPTION = """Test-stand controller for DC motors and gear reducers (CANopen CiA 402).

Runs are jobs on the stand (POST /runs → 202); analyses take stored run ids (JSON) or
uploaded CSV run files (multipart/form-data). Mutating routes need
`Authorization: Bearer <STAND_API_KEY>` when a key is configured; without one the service
listens on loopback only. Result fields are those of the `stand` command line's JSON.
"""


def default_runner(settings: Settings) -> StandRunner:
    """The stand controller on the configured bus; on ``virtual`` the drives of each
    experiment's motor or stand are simulated in this process."""
    from bus.adapters import BusConfig
    from bus.stand_bus import StandBus

    config = BusConfig(settings.bus_interface, settings.bus_channel, settings.bus_bitrate)
    options: dict[str, Any] = dict(SIMULATED_MASTER_OPTIONS) if config.interface == "virtual" else {}

    def open_bus(profile: str, seed: int | None) -> StandBus:
        return StandBus(profile, config, seed=seed, **options)

    return ControllerRunner(open_bus, settings.runs_dir, settings.time_mode)


def create_app(settings: Settings | None = None,
               runner_factory: Callable[[Settings], StandRunner] | None = None,
               lock: DataDirLock | None = None) -> FastAPI:
    """Build the app; storage and stand open at start-up and close at shutdown.

    ``lock``: the data directory's lock when the caller took it already (``stand
    serve`` does, to refuse before uvicorn starts); otherwise the app takes it.
    """
    settings = settings or get_settings()
    factory = runner_factory or default_runner

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        own = lock is None or not lock.held
        held = DataDirLock(settings.data_dir).acquire() if own else lock
        assert held is not None
        try:
            storage = Storage(settings.database, settings.db_max_bytes)
            aborted = storage.recover(held)
            if aborted:
                log.warning("marked %d run(s) interrupted by a restart as aborted: %s",
                            len(aborted), ", ".join(aborted))
            if settings.upload_retention_s is not None:
                storage.prune_uploads(settings.upload_retention_s)
            jobs = JobManager(storage, factory(settings))
            app.state.settings, app.state.storage, app.state.jobs = settings, storage, jobs
            app.state.parse_lanes = parse_lanes()
            try:
                yield
            finally:
                app.state.parse_lanes.close()
                jobs.close()
                storage.close()
        finally:
            if own:
                held.release()

    app = FastAPI(title="motorstand", version="0.1.0", description=DESCRIPTION, lifespan=lifespan,
                  docs_url=None, redoc_url=None)
    app.state.settings = settings
    errors.install(app)
    app.add_middleware(BodyLimit, limit=settings.upload_limit_bytes)
    if settings.api_key is None:
        app.add_middleware(LoopbackOnly)  # outermost: refused before anything is read
    for router in (health.router, profiles.router, runs.router, analysis.router, results.router,
                   stand.router, batch.router):
        app.include_router(router)
    pages.install(app)
    return app
