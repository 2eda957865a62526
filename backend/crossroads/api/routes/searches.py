"""Failure searches in the studio: start one from a scenario (202; it runs in the background),
follow its progress, browse its failures (parameters, distance from nominal, 3D playback of the
minimal episode), save one as a regression scenario, read its report.

A search runs in this process (:class:`~crossroads.search.engine.SearchRunner` in a thread; its
episodes in worker processes or on Ray, as batches do), at most ``MAX_RUNNING`` at once. Its live
progress carries the elapsed time since it (re)started here, the rate of search episodes and the
ETA of the search phase. A search the server stopped (a shutdown cancels it, recording why) or
left unfinished (the process was killed) reads ``state: interrupted``; POST /searches/{id}/resume
goes on with it from the store.
"""

from __future__ import annotations

import threading
import time
from typing import Annotated, Any, Literal

from fastapi import APIRouter, HTTPException, Path, Request, status
from fastapi.responses import HTMLResponse, PlainTextResponse
from pydantic import BaseModel, ConfigDict, Field

from crossroads.api.deps import OptionsDep, SessionDep, SettingsDep, StoreDep, unprocessable
from crossroads.api.routes.policies import models_dir, policy_ref
from crossroads.scenario.spec import validate_scenario
from crossroads.search import records
from crossroads.search.collection import failure_yaml
from crossroads.search.engine import SearchRunner, create_search_for, failure_json, summarize_search
from crossroads.search.space import network_problems_of, validate_space
from crossroads.store import Store, crud
from crossroads.store.search_tables import Search
from crossroads.store.tables import MAX_ROW_ID
from crossroads.validation import SpecError

router = APIRouter(prefix="/searches", tags=["searches"])

MAX_BUDGET = 5000  # episodes a search started from the studio may propose
MAX_RUNNING = 1  # searches running at once in this process (each uses every worker it is given)
SearchId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="id of a search")]
FailureId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="id of a failure of the search")]


class SearchCreate(BaseModel):
    """A search to start: a space (its ``scenario`` inline, a mapping, or ``scenario_id``)."""

    model_config = ConfigDict(extra="forbid")

    policy: str = Field(description="A policy name as listed by GET /policies.")
    space: dict[str, Any] = Field(description="The search space (docs/guide/failure-search.md); its "
                                  "scenario given inline, or left out with scenario_id.")
    scenario_id: int | None = Field(default=None, ge=1, le=MAX_ROW_ID,
                                    description="A stored scenario as the nominal one.")
    budget: int = Field(default=200, ge=1, le=MAX_BUDGET, description="Episodes the search proposes.")
    sampler: Literal["tpe", "random"] = "tpe"
    seed: int = Field(default=0, ge=0, le=2**31 - 1)
    workers: int | None = Field(default=None, ge=1, description="Episodes at once.")
    generation: int | None = Field(default=None, ge=1, le=64, description="Trials proposed at once.")
    shrink_steps: int | None = Field(default=None, ge=0, le=200)


class _Running:
    """The searches this process runs (a registry on ``app.state``)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.runners: dict[int, SearchRunner] = {}
        self.started: dict[int, tuple[float, int | None]] = {}  # wall time, search episodes then

    def add(self, search_id: int, runner: SearchRunner) -> None:
        with self.lock:
            self.runners[search_id] = runner
            self.started[search_id] = (time.time(), None)  # the count: from its first progress

    def live(self, search_id: int) -> SearchRunner | None:
        with self.lock:
            runner = self.runners.get(search_id)
        return runner if runner is not None and runner.running else None

    def running(self) -> int:
        with self.lock:
            ids = list(self.runners)
        return sum(self.live(i) is not None for i in ids)


def _registry(request: Request) -> _Running:
    registry = getattr(request.app.state, "searches", None)
    if registry is None:
        registry = request.app.state.searches = _Running()
    return registry  # type: ignore[no-any-return]


def stop_all(app: Any, timeout_s: float = 10.0) -> None:
    """Cancel the searches of this process (the app's shutdown): they resume from the store."""
    registry = getattr(app.state, "searches", None)
    if registry is None:
        return
    with registry.lock:
        runners = list(registry.runners.values())
    for runner in runners:
        runner.cancel()
    for runner in runners:
        try:
            runner.wait(timeout_s)
        except BaseException:  # noqa: BLE001 - it failed or was cancelled: nothing to wait for
            pass
        try:
            with runner.store.session() as session:
                row = records.get_search(session=session, search_id=runner.search_id)
                if row is not None and row.status == "cancelled" and row.error is None:
                    records.set_search_status(session=session, search_id=row.id, status="cancelled",
                                              error=INTERRUPTED)
        except Exception:  # noqa: BLE001 - the store went first: it reads cancelled
            pass


INTERRUPTED = "interrupted: the server stopped while the search ran; resume it"


def _state(status: str, error: str | None, live: bool) -> str:
    """What the studio shows: the stored status, except ``interrupted`` for a search the server
    stopped or left unfinished (status queued or running with no runner in this process)."""
    if live:
        return "running"
    if status in ("queued", "running") or (status == "cancelled" and error == INTERRUPTED):
        return "interrupted"
    return status


def _timing(registry: _Running, search_id: int, progress: dict[str, Any]) -> dict[str, Any]:
    """Elapsed time since the search (re)started here, its rate of search episodes and the ETA
    of the search phase (the shrinking's length is not known in advance)."""
    with registry.lock:
        began, at_start = registry.started.get(search_id, (time.time(), None))
        if at_start is None:
            at_start = int(progress["searched"])
            registry.started[search_id] = (began, at_start)
    elapsed = max(0.0, time.time() - began)
    since = int(progress["searched"]) - at_start
    rate = since / elapsed * 60.0 if since > 0 and elapsed > 0 else None
    left = int(progress["budget"]) - int(progress["searched"])
    eta = round(left / rate * 60.0) if rate and progress.get("phase") == "search" else None
    return {"elapsed_s": float(round(elapsed)), "rate_per_min": None if rate is None else round(rate, 2),
            "eta_s": None if eta is None else float(eta)}


def _get(session: Any, search_id: int) -> Search:
    search = records.get_search(session=session, search_id=search_id)
    if search is None:
        raise HTTPException(status_code=404, detail=f"no search {search_id}")
    return search


def _public(store: Store, search_id: int, registry: _Running) -> dict[str, Any]:
    summary = summarize_search(store, search_id)
    runner = registry.live(search_id)
    progress = None
    if runner is not None:
        progress = runner.progress.to_json()
        progress.update(_timing(registry, search_id, progress))
    summary["progress"] = progress
    summary["state"] = _state(summary["status"], summary["error"], runner is not None)
    summary.pop("failure_list")
    return summary


@router.post("", status_code=status.HTTP_202_ACCEPTED)
def start_search(body: SearchCreate, request: Request, session: SessionDep, store: StoreDep,
                 settings: SettingsDep, options: OptionsDep) -> dict[str, Any]:
    """Store a search and start it in the background; answers at once with its id (202).
    Follow it with GET /searches/{id}. 409 while another search runs in this process."""
    registry = _registry(request)
    if registry.running() >= MAX_RUNNING:
        raise HTTPException(status_code=409, detail="a search is running already; cancel it or wait")
    if body.workers is not None and body.workers > settings.max_batch_workers:
        raise unprocessable([("workers", f"at most {settings.max_batch_workers} on this server "
                                         "(setting max_batch_workers)")])
    ref = policy_ref(body.policy, models_dir(options.models_dir))
    data = dict(body.space)
    if body.scenario_id is not None:
        if "scenario" in data:
            raise unprocessable([("space.scenario", "give the scenario inline or scenario_id, not both")])
        row = crud.get_scenario(session=session, scenario_id=body.scenario_id)
        if row is None:
            raise unprocessable([("scenario_id", f"no scenario {body.scenario_id}")])
        data["scenario"] = row.spec
    elif not isinstance(data.get("scenario"), dict):
        # a client never names a server path
        raise unprocessable([("space.scenario", "give the nominal scenario inline (a mapping) or scenario_id")])
    try:
        space = validate_space(data, source="space", base_dir=settings.data_dir)
        problems = network_problems_of(space)
    except SpecError as exc:
        raise unprocessable([(f"space.{f}" if f else "space", m) for f, m in exc.problems]) from None
    if problems:
        raise unprocessable([(f"space.{f}", m) for f, m in problems])
    workers = body.workers or settings.max_batch_workers
    search_id = create_search_for(store, space=space, policy=ref, budget=body.budget,
                                  sampler=body.sampler, seed=body.seed,
                                  generation=body.generation or workers,
                                  shrink_steps=body.shrink_steps)
    runner = SearchRunner(store, search_id, workers=workers, ray_address=settings.ray_address,
                          data_dir=settings.data_dir)
    registry.add(search_id, runner)
    runner.start()
    return {"id": search_id, "status": "running", "url": f"/api/searches/{search_id}"}


@router.post("/{search_id}/resume", status_code=status.HTTP_202_ACCEPTED)
def resume_search(search_id: SearchId, request: Request, session: SessionDep, store: StoreDep,
                  settings: SettingsDep) -> dict[str, Any]:
    """Go on with an interrupted or cancelled search from the store (the episodes recorded are
    kept; the optimiser proposes what it would have). 409 while it, or another search, runs here,
    and for a search that is done or failed."""
    registry = _registry(request)
    search = _get(session, search_id)
    if registry.live(search_id) is not None:
        raise HTTPException(status_code=409, detail=f"search {search_id} is running already")
    state = _state(search.status, search.error, False)
    if state not in ("interrupted", "cancelled"):
        raise HTTPException(status_code=409, detail=f"search {search_id} is {state}: only an interrupted "
                                                    "or cancelled search can be resumed")
    if registry.running() >= MAX_RUNNING:
        raise HTTPException(status_code=409, detail="a search is running already; cancel it or wait")
    runner = SearchRunner(store, search_id, workers=search.workers or settings.max_batch_workers,
                          ray_address=settings.ray_address, data_dir=settings.data_dir)
    registry.add(search_id, runner)
    runner.start()
    return {"id": search_id, "status": "running", "url": f"/api/searches/{search_id}"}


@router.get("")
def list_searches(request: Request, session: SessionDep, store: StoreDep) -> list[dict[str, Any]]:
    """The 50 newest searches, with live progress for those running here."""
    registry = _registry(request)
    return [_public(store, s.id, registry) for s in records.list_searches(session=session, limit=50)]


@router.get("/{search_id}")
def get_search(search_id: SearchId, request: Request, session: SessionDep, store: StoreDep) -> dict[str, Any]:
    """A search: its figures (episodes, failing ones, failures kept, best objective), ``state``
    (its status, or ``interrupted``) and, while it runs here, its live progress (phase, episodes,
    failures so far, elapsed time, rate and ETA)."""
    _get(session, search_id)
    return _public(store, search_id, _registry(request))


@router.post("/{search_id}/cancel", status_code=status.HTTP_202_ACCEPTED)
def cancel_search(search_id: SearchId, request: Request, session: SessionDep) -> dict[str, Any]:
    """Stop a search running here (its episodes in flight are dropped; it can be resumed with
    ``crossroads search --resume``). 409 when it does not run in this process."""
    _get(session, search_id)
    runner = _registry(request).live(search_id)
    if runner is None:
        raise HTTPException(status_code=409, detail=f"search {search_id} is not running here")
    runner.cancel()
    return {"id": search_id, "status": "cancelling"}


@router.get("/{search_id}/trials")
def search_trials(search_id: SearchId, session: SessionDep) -> list[dict[str, Any]]:
    """Every recorded episode of the search: number, kind (search | shrink), parameters, seed,
    outcome, objective, batch (for playback)."""
    _get(session, search_id)
    return [{"number": t.number, "kind": t.kind, "parent": t.parent, "params": t.params, "seed": t.seed,
             "outcome": t.outcome, "objective": t.objective, "batch_id": t.batch_id}
            for t in records.trials(session=session, search_id=search_id) if t.outcome is not None]


def _failure(session: Any, search_id: int, failure_id: int) -> Any:
    row = records.get_failure(session=session, search_id=search_id, failure_id=failure_id)
    if row is None:
        raise HTTPException(status_code=404, detail=f"search {search_id} has no failure {failure_id}")
    return row


@router.get("/{search_id}/failures")
def search_failures(search_id: SearchId, session: SessionDep) -> list[dict[str, Any]]:
    """The failures kept (shrunk): parameters, distance from nominal, what is still off nominal,
    and ``playback``: the 3D playback of the minimal episode."""
    _get(session, search_id)
    batches = {t.number: t.batch_id for t in records.trials(session=session, search_id=search_id)}
    out = []
    for row in records.failures(session=session, search_id=search_id):
        item = failure_json(row)
        batch_id = batches.get(row.minimal_number)
        item["batch_id"] = batch_id
        item["playback"] = None if batch_id is None else f"/api/playback/{batch_id}/0"
        item.pop("yaml_path")  # a server path
        out.append(item)
    return out


@router.get("/{search_id}/failures/{failure_id}/scenario.yaml", response_class=PlainTextResponse)
def failure_scenario(search_id: SearchId, failure_id: FailureId, session: SessionDep) -> PlainTextResponse:
    """The failure as a scenario file (``crossroads evaluate`` on it replays the episode)."""
    row = _failure(session, search_id, failure_id)
    spec = validate_scenario(row.spec, source=f"failure {failure_id}", check_references=False)
    text = failure_yaml(spec, header=[f"A {row.outcome} found by search {search_id}; seed {row.seed}."])
    return PlainTextResponse(text, media_type="application/yaml", headers={
        "Content-Disposition": f'attachment; filename="{spec.name}.yaml"'})


@router.post("/{search_id}/failures/{failure_id}/save", status_code=status.HTTP_201_CREATED)
def save_failure(search_id: SearchId, failure_id: FailureId, session: SessionDep) -> dict[str, Any]:
    """Save the failure as a regression scenario: a stored scenario the studio lists and runs
    batches of (idempotent: the same failure gives the same scenario)."""
    row = _failure(session, search_id, failure_id)
    spec = validate_scenario(row.spec, source=f"failure {failure_id}", check_references=False)
    scenario = crud.get_or_create_scenario(session=session, spec=spec)
    return {"scenario_id": scenario.id, "name": scenario.name, "url": f"/api/scenarios/{scenario.id}"}


@router.get("/{search_id}/report", response_class=HTMLResponse)
def search_report(search_id: SearchId, session: SessionDep, store: StoreDep) -> HTMLResponse:
    """The search's report: outcome against each parameter over every episode, and the failures."""
    from crossroads.search.report import render_html

    _get(session, search_id)
    return HTMLResponse(render_html(store, search_id))
