"""The Crossroads API: a FastAPI app built from Settings; routers per resource in routes/.

The lifespan opens (and migrates) the results store named by the settings, starts the batch
job registry (at most ``max_concurrent_batches`` running, the rest queued) and resumes the
batches a previous process left queued or running (``resume_batches``); on shutdown it stops the
live runs and the running batches (left ``queued`` for the next start) and closes the store.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse

from crossroads import __version__
from crossroads.api.deps import ApiOptions
from crossroads.api.jobs import JobRegistry
from crossroads.api.live import LiveRuns
from crossroads.api.routes import (
    batches,
    episodes,
    health,
    intersections,
    live,
    playback,
    policies,
    reports,
    scenarios,
    uploads,
)
from crossroads.api.static import mount_frontend
from crossroads.evaluation.policies import PolicyError
from crossroads.network.junction import JunctionError
from crossroads.network.resolve import NetworkNotFoundError
from crossroads.settings import Settings
from crossroads.store import open_store
from crossroads.validation import SpecError

SHUTDOWN_WAIT_S = 10.0  # [s] how long shutdown waits for cancelled batches to stop


@asynccontextmanager
async def lifespan(app: FastAPI) -> AsyncIterator[None]:
    settings: Settings = app.state.settings
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    store = open_store(settings.database_url)
    jobs = JobRegistry(store, data_dir=settings.data_dir, ray_address=settings.ray_address,
                       max_running=settings.max_concurrent_batches)
    live_runs = LiveRuns(host=settings.host)
    app.state.store, app.state.jobs, app.state.live = store, jobs, live_runs
    if settings.resume_batches:
        jobs.resume_unfinished()  # returns at once: the batches run in the background
    try:
        yield
    finally:
        live_runs.shutdown()
        jobs.shutdown(SHUTDOWN_WAIT_S)
        app.state.store = app.state.jobs = app.state.live = None
        store.close()


def create_app(settings: Settings | None = None, options: ApiOptions | None = None) -> FastAPI:
    settings = settings or Settings()
    app = FastAPI(
        title="Crossroads",
        version=__version__,
        summary="Scenario studio and evaluator for driving policies at signalized intersections",
        lifespan=lifespan,
    )
    app.state.settings = settings
    app.state.options = options or ApiOptions()
    app.state.store = app.state.jobs = app.state.live = None
    app.include_router(health.router, prefix="/api")
    app.include_router(uploads.router, prefix="/api")  # before /intersections/{name}
    app.include_router(intersections.router, prefix="/api")
    app.include_router(scenarios.router, prefix="/api")
    app.include_router(policies.router, prefix="/api")
    app.include_router(batches.router, prefix="/api")
    app.include_router(episodes.router, prefix="/api")
    app.include_router(reports.router, prefix="/api")
    app.include_router(playback.router, prefix="/api")
    app.include_router(live.router, prefix="/api")

    # Domain errors become clear HTTP answers in one place, not in every route.
    @app.exception_handler(NetworkNotFoundError)
    async def _not_found(_: Request, exc: NetworkNotFoundError) -> JSONResponse:
        return JSONResponse(status_code=404, content={"detail": str(exc)})

    @app.exception_handler(SpecError)
    @app.exception_handler(JunctionError)
    @app.exception_handler(PolicyError)
    async def _unprocessable(_: Request, exc: Exception) -> JSONResponse:
        return JSONResponse(status_code=422, content={"detail": str(exc)})

    mount_frontend(app)  # last: its catch-all route must not shadow the API
    return app
