"""Dependencies shared by the routes: settings, the store and a session on it, the job registry.

The store, the job registry and the live runs are opened once by the app's lifespan (``api/main.py``) and live on
``app.state``; routes never open their own. Errors of user input are raised through
:func:`unprocessable`, so every 422 of the API has FastAPI's own shape
(``{"detail": [{"loc": [...], "msg": ..., "type": ...}]}``) and names the field.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from fastapi import Depends, HTTPException, Request
from sqlalchemy.orm import Session

from crossroads.api.jobs import JobRegistry
from crossroads.api.live import LiveRuns
from crossroads.settings import Settings
from crossroads.store import Store


@dataclass(frozen=True)
class ApiOptions:
    """Limits and places of the API that are not (yet) service settings."""

    upload_max_bytes: int = 20 * 2**20  # [bytes] largest .net.xml accepted by the upload
    models_dir: Path | None = None  # where checkpoints (*.pt) and their cards are; None: <repo>/models

    def __post_init__(self) -> None:
        if self.upload_max_bytes < 1:
            raise ValueError(f"upload_max_bytes must be >= 1, got {self.upload_max_bytes}")


def get_settings(request: Request) -> Settings:
    return request.app.state.settings


def get_options(request: Request) -> ApiOptions:
    return request.app.state.options


def get_store(request: Request) -> Store:
    store = getattr(request.app.state, "store", None)
    if store is None:  # the lifespan did not run (an app used without starting it)
        raise HTTPException(status_code=503, detail="the results store is not open")
    return store


def get_session(store: Annotated[Store, Depends(get_store)]) -> Iterator[Session]:
    with store.session() as session:
        yield session


def get_jobs(request: Request) -> JobRegistry:
    jobs = getattr(request.app.state, "jobs", None)
    if jobs is None:
        raise HTTPException(status_code=503, detail="the batch runner is not started")
    return jobs


def get_live(request: Request) -> LiveRuns:
    live = getattr(request.app.state, "live", None)
    if live is None:
        raise HTTPException(status_code=503, detail="live runs are not available (the app is not started)")
    return live


SettingsDep = Annotated[Settings, Depends(get_settings)]
OptionsDep = Annotated[ApiOptions, Depends(get_options)]
StoreDep = Annotated[Store, Depends(get_store)]
SessionDep = Annotated[Session, Depends(get_session)]
JobsDep = Annotated[JobRegistry, Depends(get_jobs)]
LiveDep = Annotated[LiveRuns, Depends(get_live)]


def loc_of(field: str, prefix: Sequence[str | int] = ("body",)) -> list[str | int]:
    """``"abnormal.overspeed.share"`` → ``["body", "abnormal", "overspeed", "share"]``."""
    parts: list[str | int] = [int(p) if p.isdigit() else p for p in field.split(".") if p]
    return [*prefix, *parts]


def unprocessable(problems: Iterable[tuple[str, str]], *,
                  prefix: Sequence[str | int] = ("body",)) -> HTTPException:
    """A 422 naming each ``(field, message)`` in FastAPI's validation-error shape."""
    return HTTPException(status_code=422, detail=[
        {"loc": loc_of(field, prefix), "msg": message, "type": "value_error"}
        for field, message in problems])
