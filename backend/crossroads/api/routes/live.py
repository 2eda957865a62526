"""Live runs: one episode of a scenario driven in the 3D view while it runs.

``POST /live`` checks the request like a batch (422 naming the field), starts the episode in a
child process and answers at once (202) with the viewer's URL; ``GET /live/{id}`` tells where it
stands and its result; ``POST /live/{id}/stop`` ends it early. See :mod:`crossroads.api.live`.

The viewer's page is ``/live/{id}/view/`` and its WebSocket ``/live/{id}/view``, handed on to the
run's viser server (on a loopback port) by :mod:`crossroads.api.viewer_proxy`.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, HTTPException, Request, Response, WebSocket, status
from fastapi.responses import HTMLResponse, RedirectResponse

from crossroads.api.deps import LiveDep, OptionsDep, SessionDep, SettingsDep, unprocessable
from crossroads.api.live import LiveBusyError, LiveRun
from crossroads.api.params import LiveId, Page, paging
from crossroads.api.routes.policies import models_dir, policy_ref
from crossroads.api.routes.scenarios import parse_scenario
from crossroads.api.schemas import LiveCreate, LivePublic
from crossroads.api.viewer_proxy import fetch_page, proxy_websocket
from crossroads.scenario.spec import ScenarioSpec, run_seeds
from crossroads.settings import Settings
from crossroads.store import crud

router = APIRouter(prefix="/live", tags=["live"])


def _scenario(body: LiveCreate, session: SessionDep, settings: Settings) -> ScenarioSpec:
    """The scenario of the request: the stored one or the one given inline (not stored)."""
    if (body.scenario_id is None) == (body.scenario is None):
        raise unprocessable([("scenario_id", "give exactly one of scenario_id (a stored scenario) "
                                             "and scenario (one given inline)")])
    if body.scenario is not None:
        return parse_scenario(body.scenario, settings, prefix=("body", "scenario"))
    row = crud.get_scenario(session=session, scenario_id=body.scenario_id)
    if row is None:
        raise unprocessable([("scenario_id", f"no scenario {body.scenario_id}")])
    return parse_scenario(row.spec, settings, prefix=("body", "scenario_id"))


def view_path(run_id: int) -> str:
    """Where the browser opens a live run's viewer (its WebSocket: the same without the slash)."""
    return f"/api/live/{run_id}/view/"


def _public(run: LiveRun, request: Request) -> LivePublic:
    return LivePublic(**run.public(), url=view_path(run.id))


def _get(live: LiveDep, run_id: int) -> LiveRun:
    run = live.get(run_id)
    if run is None:
        raise HTTPException(status_code=404, detail=f"no live run {run_id} (this server keeps the "
                                                    "latest few)")
    return run


@router.post("", status_code=status.HTTP_202_ACCEPTED,
             responses={429: {"description": "as many live runs as allowed are running already"}})
def start_live(body: LiveCreate, request: Request, session: SessionDep, settings: SettingsDep,
               options: OptionsDep, live: LiveDep) -> LivePublic:
    """Start one episode in the 3D view; answers at once with the viewer's ``url``. The episode
    starts when a first tab opens the viewer (or after a few seconds) and runs at ``speed``."""
    ref = policy_ref(body.policy, models_dir(options.models_dir), data_dir=settings.data_dir)
    spec = _scenario(body, session, settings)
    seed = body.seed if body.seed is not None else run_seeds(spec, 1)[0]
    try:
        run = live.start(spec=spec.model_dump(mode="json"), base_dir=str(settings.data_dir),
                         policy_ref=ref, policy_name=body.policy, seed=seed, speed=body.speed)
    except LiveBusyError as exc:
        raise HTTPException(status_code=429, detail=str(exc)) from None
    return _public(run, request)


@router.get("")
def list_live(request: Request, live: LiveDep, response: Response,
              page: Annotated[Page, Depends(paging(100, 100))]) -> list[LivePublic]:
    """The live runs this server keeps (running and the latest finished ones)."""
    return [_public(r, request) for r in page.slice(live.list(), response)]


@router.get("/{run_id}")
def get_live(run_id: LiveId, request: Request, live: LiveDep) -> LivePublic:
    return _public(_get(live, run_id), request)


@router.post("/{run_id}/stop", status_code=status.HTTP_202_ACCEPTED)
def stop_live(run_id: LiveId, request: Request, live: LiveDep) -> LivePublic:
    """End a live run at its next step (it ends ``stopped``; the viewer stays open)."""
    run = _get(live, run_id)
    live.stop(run_id)
    return _public(run, request)


@router.get("/{run_id}/view", include_in_schema=False)
def view_without_slash(run_id: LiveId) -> RedirectResponse:
    return RedirectResponse(view_path(run_id), status_code=307)


@router.get("/{run_id}/view/", response_class=HTMLResponse)
def view_page(run_id: LiveId, request: Request, live: LiveDep) -> Response:
    """The live run's 3D view (viser's page, from the run's own viewer)."""
    run = _get(live, run_id)
    return fetch_page(run.port, "/", request.headers.get("accept-encoding", ""))


@router.websocket("/{run_id}/view")
@router.websocket("/{run_id}/view/")
async def view_socket(websocket: WebSocket, run_id: LiveId) -> None:
    """The viewer's WebSocket, joined to the run's viser server (refused when the run is gone)."""
    live = getattr(websocket.app.state, "live", None)
    run = live.get(run_id) if live is not None else None
    if run is None:
        await websocket.close(code=1008, reason=f"no live run {run_id}")
        return
    settings = websocket.app.state.settings
    await proxy_websocket(websocket, run.port, allowed_hosts=tuple(settings.allowed_hosts))
