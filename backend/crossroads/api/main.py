"""The Crossroads API: a FastAPI app built from Settings; routers per resource in routes/."""

from __future__ import annotations

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse

from crossroads import __version__
from crossroads.api.routes import health, intersections
from crossroads.network.junction import JunctionError
from crossroads.network.resolve import NetworkNotFoundError
from crossroads.settings import Settings
from crossroads.validation import SpecError


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings()
    app = FastAPI(
        title="Crossroads",
        version=__version__,
        summary="Scenario studio and evaluator for driving policies at signalized intersections",
    )
    app.state.settings = settings
    app.include_router(health.router, prefix="/api")
    app.include_router(intersections.router, prefix="/api")

    # Domain errors become clear HTTP answers in one place, not in every route.
    @app.exception_handler(NetworkNotFoundError)
    async def _not_found(_: Request, exc: NetworkNotFoundError) -> JSONResponse:
        return JSONResponse(status_code=404, content={"detail": str(exc)})

    @app.exception_handler(SpecError)
    @app.exception_handler(JunctionError)
    async def _unprocessable(_: Request, exc: Exception) -> JSONResponse:
        return JSONResponse(status_code=422, content={"detail": str(exc)})

    return app
