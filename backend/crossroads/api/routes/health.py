"""GET /api/health: is the service up, and which versions does it run."""

from __future__ import annotations

from importlib.metadata import version

from fastapi import APIRouter

from crossroads import __version__

router = APIRouter(tags=["health"])


@router.get("/health")
def health() -> dict[str, str]:
    return {"status": "ok", "version": __version__, "sumo": version("eclipse-sumo")}
