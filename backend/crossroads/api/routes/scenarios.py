"""Scenarios: create, read, update, delete, validate, and the JSON Schema of a scenario; a stored
scenario as a YAML file (``GET /scenarios/{id}/scenario.yaml``) and a YAML file stored
(``POST /scenarios/import``, the file as the body), the format ``crossroads run`` reads.

A scenario is stored by its content hash (the same spec twice is one row). A scenario that
batches ran with is read-only (its results refer to it): PUT and DELETE answer 409, and a
changed scenario is POSTed as a new one. An ``{net: ...}`` intersection must name a network
uploaded through POST /intersections/upload (``uploads/<sha256>.net.xml``, relative to the data
directory); the API reads no other file of the server. What a scenario asks of its network
(approach, ego start, light phase) is checked against the network
(``scenario/network_checks.py``).
"""

from __future__ import annotations

import json
from pathlib import PurePosixPath
from typing import Annotated, Any

import yaml
from fastapi import APIRouter, Body, Depends, HTTPException, Response, status
from fastapi.responses import PlainTextResponse
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from crossroads.api.deps import SessionDep, SettingsDep, unprocessable
from crossroads.api.params import Page, ScenarioId, paging, set_total
from crossroads.api.schemas import Problem, ScenarioPublic, ScenarioValidation
from crossroads.scenario.network_checks import internal_lane_warning, network_problems
from crossroads.scenario.spec import (
    ScenarioSpec,
    canonical_json,
    content_hash,
    reference_problems,
    scenario_json_schema,
    validate_scenario,
)
from crossroads.settings import Settings
from crossroads.store import crud
from crossroads.store.tables import Batch, Scenario
from crossroads.validation import SpecError

router = APIRouter(prefix="/scenarios", tags=["scenarios"])

UPLOADS = "uploads"  # under the data directory
EXAMPLE = {
    "version": 1, "name": "my-left-turn", "intersection": "c_three_lane", "task": "left",
    "traffic": {"vehicles_per_hour": 400, "cyclists_per_hour": 100, "pedestrians_per_hour": 100},
    "abnormal": {"overspeed": {"share": 0.15, "excess": 0.2}}, "runs": 20, "seed": 0,
}
ScenarioBody = Annotated[dict[str, Any], Body(
    description="A scenario (format version 1, see GET /api/scenarios/schema)",
    openapi_examples={"left turn with over-speeding": {"value": EXAMPLE}})]


def scenario_problems(data: Any, settings: Settings) -> tuple[ScenarioSpec | None, list[tuple[str, str]]]:
    """The spec of ``data``, or its problems as ``(field, message)`` pairs."""
    try:
        spec = validate_scenario(data, source="scenario", check_references=False)
    except SpecError as exc:
        return None, list(exc.problems)
    if not isinstance(spec.intersection, str):
        net = PurePosixPath(spec.intersection.net)
        if net.is_absolute() or ".." in net.parts or net.parts[:1] != (UPLOADS,) or len(net.parts) != 2:
            return None, [("intersection.net", "must name an uploaded network, "
                           f"'{UPLOADS}/<sha256>.net.xml' (POST /api/intersections/upload)")]
    # what the spec names must exist, then agree with its network (approach, ego start, lights);
    # the data directory is the server's business: messages show it as <data>
    problems = reference_problems(spec, settings.data_dir) or network_problems(spec, settings.data_dir)
    if problems:
        return None, [(f, m.replace(str(settings.data_dir), "<data>")) for f, m in problems]
    return spec, []


def parse_scenario(data: Any, settings: Settings, *, prefix: tuple[str, ...] = ("body",)) -> ScenarioSpec:
    """The spec of ``data``; a 422 naming every faulty field otherwise."""
    spec, problems = scenario_problems(data, settings)
    if spec is None:
        raise unprocessable(problems, prefix=prefix)
    return spec


def _batch_count(session: Session, scenario_id: int) -> int:
    return int(session.scalar(select(func.count()).select_from(Batch)
                              .where(Batch.scenario_id == scenario_id)) or 0)


def _public(row: Scenario, batches: int) -> ScenarioPublic:
    return ScenarioPublic(id=row.id, name=row.name, content_hash=row.content_hash, spec=row.spec,
                          created_at=row.created_at, batches=batches)


def _get(session: Session, scenario_id: int) -> Scenario:
    row = crud.get_scenario(session=session, scenario_id=scenario_id)
    if row is None:
        raise HTTPException(status_code=404, detail=f"no scenario {scenario_id}")
    return row


@router.get("/schema")
def json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a scenario, for editors and clients."""
    return scenario_json_schema()


@router.post("/validate")
def validate(data: ScenarioBody, settings: SettingsDep) -> ScenarioValidation:
    """Check a scenario without storing it: every problem, each naming its field."""
    spec, problems = scenario_problems(data, settings)
    warning = None if spec is None else internal_lane_warning(spec, settings.data_dir)
    return ScenarioValidation(valid=not problems,
                              problems=[Problem(field=f, message=m) for f, m in problems],
                              warnings=[] if warning is None else [Problem(field="intersection", message=warning)])


@router.get("")
def list_scenarios(session: SessionDep, response: Response,
                   page: Annotated[Page, Depends(paging(100, 1000))]) -> list[ScenarioPublic]:
    """Stored scenarios, oldest first; ``X-Total-Count`` says how many there are."""
    rows = crud.list_scenarios(session=session, limit=page.limit, offset=page.offset)
    counts = crud.batch_counts(session=session, scenario_ids=[r.id for r in rows])
    set_total(response, crud.count_scenarios(session=session))
    return [_public(r, counts.get(r.id, 0)) for r in rows]


@router.post("", status_code=status.HTTP_201_CREATED,
             responses={200: {"description": "the same scenario was stored already"}})
def create_scenario(data: ScenarioBody, session: SessionDep, settings: SettingsDep,
                    response: Response) -> ScenarioPublic:
    """Store a scenario (201); the same content again answers 200 with the stored one."""
    spec = parse_scenario(data, settings)
    existing = session.scalar(select(Scenario).where(Scenario.content_hash == content_hash(spec)))
    if existing is not None:
        response.status_code = status.HTTP_200_OK
        return _public(existing, _batch_count(session, existing.id))
    row = crud.get_or_create_scenario(session=session, spec=spec)
    return _public(row, 0)


YAML_TYPE = "application/yaml"
YamlBody = Annotated[str, Body(media_type=YAML_TYPE, description="A scenario file (YAML, format version 1)")]


def scenario_yaml(spec: dict[str, Any], header: str) -> str:
    """A stored scenario as the YAML file ``crossroads run`` reads (every field, in its order)."""
    body = yaml.safe_dump(spec, sort_keys=False, allow_unicode=True, default_flow_style=False, width=100)
    return f"# {header}\n{body}"


def parse_yaml(text: str) -> Any:
    """The data of a YAML file; a 422 naming the line and column of a syntax error."""
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
        raise unprocessable([("", f"not YAML: {where}{getattr(exc, 'problem', None) or exc}")]) from None
    if not isinstance(data, dict):
        kind = "an empty file" if data is None else f"a {type(data).__name__}"
        raise unprocessable([("", f"expected a mapping of fields at the top level, got {kind}")])
    return data


@router.post("/import", status_code=status.HTTP_201_CREATED,
             responses={200: {"description": "the same scenario was stored already"}})
def import_scenario(text: YamlBody, session: SessionDep, settings: SettingsDep,
                    response: Response) -> ScenarioPublic:
    """Store a scenario given as a YAML file (the request body, ``Content-Type: application/yaml``);
    answers as ``POST /scenarios`` does, a problem naming its field."""
    return create_scenario(parse_yaml(text), session, settings, response)


@router.get("/{scenario_id}/scenario.yaml", response_class=PlainTextResponse,
            responses={200: {"content": {YAML_TYPE: {}}}})
def scenario_file(scenario_id: ScenarioId, session: SessionDep) -> PlainTextResponse:
    """A stored scenario as a YAML file (``crossroads run`` reads it; import it again here)."""
    row = _get(session, scenario_id)
    text = scenario_yaml(row.spec, f"Crossroads scenario #{row.id} ({row.name}), sha256 {row.content_hash}")
    filename = "".join(c if c.isalnum() or c in "-_." else "_" for c in row.name) or f"scenario-{row.id}"
    return PlainTextResponse(text, media_type=YAML_TYPE,
                             headers={"Content-Disposition": f'attachment; filename="{filename}.yaml"'})


@router.get("/{scenario_id}")
def get_scenario(scenario_id: ScenarioId, session: SessionDep) -> ScenarioPublic:
    row = _get(session, scenario_id)
    return _public(row, _batch_count(session, row.id))


@router.put("/{scenario_id}")
def update_scenario(scenario_id: ScenarioId, data: ScenarioBody, session: SessionDep,
                    settings: SettingsDep) -> ScenarioPublic:
    """Replace a scenario that no batch has run yet."""
    row = _get(session, scenario_id)
    spec = parse_scenario(data, settings)
    if _batch_count(session, row.id):
        raise HTTPException(status_code=409, detail=f"scenario {scenario_id} has batches and is read-only; "
                            "POST the changed scenario as a new one")
    digest = content_hash(spec)
    other = session.scalar(select(Scenario).where(Scenario.content_hash == digest, Scenario.id != row.id))
    if other is not None:
        raise HTTPException(status_code=409, detail=f"the same scenario is stored as {other.id}")
    row.name, row.content_hash, row.spec = spec.name, digest, json.loads(canonical_json(spec))
    session.commit()
    return _public(row, 0)


@router.delete("/{scenario_id}", status_code=status.HTTP_204_NO_CONTENT)
def delete_scenario(scenario_id: ScenarioId, session: SessionDep) -> Response:
    row = _get(session, scenario_id)
    if _batch_count(session, row.id):
        raise HTTPException(status_code=409, detail=f"scenario {scenario_id} has batches; delete them first")
    session.delete(row)
    session.commit()
    return Response(status_code=status.HTTP_204_NO_CONTENT)
