"""Live runs: one episode of a scenario driven in the 3D view while it runs.

``POST /live`` checks the request like a batch (422 naming the field), starts the episode in a
child process and answers at once (202) with the viewer's URL; ``GET /live/{id}`` tells where it
stands and its result; ``POST /live/{id}/stop`` ends it early. See :mod:`crossroads.api.live`.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, HTTPException, Request, Response, status

from crossroads.api.deps import LiveDep, OptionsDep, SessionDep, SettingsDep, unprocessable
from crossroads.api.live import LiveBusyError, LiveRun
from crossroads.api.params import LiveId, Page, paging
from crossroads.api.routes.playback import viewer_url
from crossroads.api.routes.policies import models_dir, policy_ref
from crossroads.api.routes.scenarios import parse_scenario
from crossroads.api.schemas import LiveCreate, LivePublic
from crossroads.evaluation.scenario import ScenarioSpec, run_seeds
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


def _public(run: LiveRun, request: Request) -> LivePublic:
    return LivePublic(**run.public(), url=viewer_url(request, run.port))


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
