"""The Crossroads API: a FastAPI app built from Settings; routers per resource in routes/.

The lifespan opens (and migrates) the results store named by the settings, starts the batch
job registry (at most ``max_concurrent_batches`` running, the rest queued) and resumes the
batches a previous process left queued, running or interrupted (``resume_batches``; otherwise
they show ``interrupted`` until a user resumes one); on shutdown it stops the live runs and the
running batches (marked ``interrupted`` for the next start) and closes the store.

In front of every route: :class:`~crossroads.api.guard.RequestGuard` (the Host, the access token,
the Origin of state-changing requests) and :class:`~crossroads.api.body_limit.BodyLimit` (the
request body limit); errors become answers in :mod:`crossroads.api.errors`.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI

from crossroads import __version__
from crossroads.api.body_limit import BodyLimit, own_body_routes
from crossroads.api.deps import ApiOptions
from crossroads.api.errors import install_error_handlers
from crossroads.api.guard import RequestGuard
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
    policy_uploads,
    reports,
    scenarios,
    searches,
    uploads,
)
from crossroads.api.static import mount_docs, mount_frontend
from crossroads.settings import Settings
from crossroads.store import open_store

SHUTDOWN_WAIT_S = 10.0  # [s] how long shutdown waits for cancelled batches to stop


@asynccontextmanager
async def lifespan(app: FastAPI) -> AsyncIterator[None]:
    settings: Settings = app.state.settings
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    store = open_store(settings.database_url)
    jobs = JobRegistry(store, data_dir=settings.data_dir, ray_address=settings.ray_address,
                       max_running=settings.max_concurrent_batches,
                       episode_wall_limit_s=settings.episode_wall_limit_s)
    live_runs = LiveRuns()  # its viewers listen on loopback: reached through the API's port
    app.state.store, app.state.jobs, app.state.live = store, jobs, live_runs
    if settings.resume_batches:
        jobs.resume_unfinished()  # returns at once: the batches run in the background
    jobs.start_heartbeat()  # batches a stopped process left behind are marked interrupted
    try:
        yield
    finally:
        live_runs.shutdown()
        searches.stop_all(app, SHUTDOWN_WAIT_S)  # cancelled: they resume from the store
        jobs.shutdown(SHUTDOWN_WAIT_S)
        app.state.store = app.state.jobs = app.state.live = None
        store.close()


def create_app(settings: Settings | None = None, options: ApiOptions | None = None) -> FastAPI:
    settings = settings or Settings()
    if settings.public and settings.token is None:
        raise ValueError(f"the API would listen on {settings.host}, beyond this machine, without an access "
                         "token: set one (CROSSROADS_TOKEN; `crossroads serve` generates one)")
    app = FastAPI(
        title="Crossroads",
        version=__version__,
        summary="Scenario studio and evaluator for driving policies at signalized intersections",
        lifespan=lifespan,
        docs_url=None,  # /docs and /redoc: mount_docs, their scripts served locally
        redoc_url=None,
    )
    app.state.settings = settings
    app.state.options = options or ApiOptions()
    app.state.store = app.state.jobs = app.state.live = None
    app.include_router(health.router, prefix="/api")
    app.include_router(uploads.router, prefix="/api")  # before /intersections/{name}
    app.include_router(intersections.router, prefix="/api")
    app.include_router(scenarios.router, prefix="/api")
    app.include_router(policies.router, prefix="/api")
    app.include_router(policy_uploads.router, prefix="/api")  # ONNX policies: POST /policies/upload, ...
    app.include_router(batches.router, prefix="/api")
    app.include_router(episodes.router, prefix="/api")
    app.include_router(reports.router, prefix="/api")
    app.include_router(playback.router, prefix="/api")
    app.include_router(live.router, prefix="/api")
    app.include_router(searches.router, prefix="/api")

    install_error_handlers(app)
    mount_docs(app)
    mount_frontend(app)  # last: its catch-all route must not shadow the API
    # the last added runs first: the guard refuses a request before its body is read
    app.add_middleware(BodyLimit, max_bytes=settings.json_body_max_bytes, exempt=own_body_routes(app.routes))
    app.add_middleware(RequestGuard, settings=settings)
    return app
