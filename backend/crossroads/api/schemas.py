"""Request and response models of the API, one family per resource.

Scenario bodies themselves are validated by :class:`~crossroads.scenario.spec.ScenarioSpec`
(one definition of a scenario for files, the CLI and the API); these models wrap them.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from crossroads.scenario.spec import MAX_RUNS
from crossroads.settings import MAX_BATCH_WORKERS
from crossroads.store.tables import MAX_ROW_ID

# What a client sends: no unknown keys, no coercion, no NaN or infinities.
_IN = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


# --- scenarios ------------------------------------------------------------------------------------


class Problem(BaseModel):
    field: str = Field(description="dotted path of the faulty field ('' for the whole body)")
    message: str


class ScenarioValidation(BaseModel):
    valid: bool
    problems: list[Problem]
    warnings: list[Problem] = Field(default_factory=list, description=(
        "what does not stop the scenario from running but should be known: SUMO's internal lanes "
        "of the ego's movements running off its candidate paths"))


class ScenarioPublic(BaseModel):
    id: int
    name: str
    content_hash: str = Field(description="sha256 of the canonical spec JSON: the scenario's identity")
    spec: dict[str, Any] = Field(description="the scenario, every default filled in")
    created_at: datetime
    batches: int = Field(description="batches run with this scenario (such a scenario is read-only)")


# --- policies -------------------------------------------------------------------------------------


class PolicyPublic(BaseModel):
    name: str = Field(description="what POST /batches takes as `policy`")
    kind: Literal["builtin", "checkpoint", "onnx"]
    file: str | None = Field(None, description="checkpoint file, relative to the models directory (an uploaded "
                                               "ONNX policy's: to the uploads)")
    shield: bool = Field(False, description="its actions pass the safety shield (idc.shield), not the paper's")
    size_bytes: int | None = None
    card: dict[str, Any] | None = Field(None, description="the model card, when one lies beside it")
    sha256: str | None = Field(None, description="sha256 of an uploaded policy's file, hex")


# --- batches --------------------------------------------------------------------------------------


class BatchCreate(BaseModel):
    """A batch: a stored scenario (``scenario_id``) or one given inline (``scenario``), a policy
    and how many seeded runs."""

    model_config = _IN

    scenario_id: int | None = Field(None, ge=1, le=MAX_ROW_ID, description="id of a stored scenario")
    scenario: dict[str, Any] | None = Field(
        None, description="a scenario given inline (stored like POST /scenarios)")
    policy: str = Field("rule", min_length=1, max_length=200,
                        description="a policy listed by GET /policies")
    runs: int | None = Field(None, ge=1, le=MAX_RUNS, description="episodes; default: the scenario's runs")
    workers: int | None = Field(
        None, ge=1, le=MAX_BATCH_WORKERS,
        description="worker processes; default: one per CPU; at most the server's max_batch_workers")
    traces: Literal["all", "failed", "none"] = Field(
        "failed", description="which episodes keep their trace ('failed': every outcome but passed)")


class BatchAccepted(BaseModel):
    id: int
    status: str
    url: str
    events: str
    queue_position: int | None = Field(
        None, description="set when the batch waits for a free slot (1 = next to start)")
    warnings: list[str] = Field(
        default_factory=list,
        description="what the batch's network gave reason to warn about, as stored with the batch "
        "(the same as `warnings` of GET /batches/{id}); said at once, before any run, so that a "
        "long batch is not waited out before the warning is seen")


class BatchProgress(BaseModel):
    done: int = Field(description="runs recorded (errors included)")
    total: int
    passed: int
    errors: int
    fraction: float
    elapsed_s: float | None = Field(None, description="[s] wall-clock since the batch last started (a "
                                    "resumed batch: since it was resumed), to its end once ended, to "
                                    "its last sign of life when interrupted; null before it starts")
    since_start: int = Field(0, description="runs recorded since it last started (the rate's count)")
    rate_per_min: float | None = Field(None, description="[runs/min] since it last started; null "
                                       "before its first run is recorded")
    eta_s: float | None = Field(None, description="[s] the runs left at that rate; only while running")


class BatchSummary(BaseModel):
    """Figures over the recorded episodes: pass rate = passed / (recorded − errors), with its
    Wilson 95 % interval; travel time over the passed episodes [s]."""

    recorded: int
    judged: int
    passed: int
    errors: int
    pass_rate: float | None
    wilson_low: float
    wilson_high: float
    travel_time_mean_s: float | None
    travel_time_std_s: float | None
    outcome_counts: dict[str, int]
    blocked: int = Field(0, description="timeouts behind a participant that barred every candidate "
                         "path the whole episode (the world's failure; still in the judged runs)")


class BatchPublic(BaseModel):
    id: int
    scenario_id: int
    scenario: str
    policy: str
    status: Literal["queued", "running", "done", "cancelled", "failed", "interrupted"] = Field(
        description="interrupted: the server stopped while the batch ran or waited (POST "
        "/batches/{id}/resume goes on with it; a restart with resume_batches does so itself)")
    runs: int
    traces: str
    workers: int | None
    executor: str | None
    error: str | None
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    progress: BatchProgress
    queue_position: int | None = Field(
        None, description="while the batch waits for a free slot (settings: max_concurrent_batches): "
        "1 = next to start; null otherwise")
    cancel_requested: bool = Field(
        False, description="a cancel was asked for (the batch ends `cancelled` and is never resumed)")
    warnings: list[str] = Field(
        default_factory=list,
        description="what the batch's network gave reason to warn about when the batch was created "
        "(e.g. SUMO's internal lanes of the ego's movements running more than half the ego's width "
        "from its candidate paths: the scenario runs, but SUMO sees the ego elsewhere than it "
        "drives); kept with the batch, whatever the network has become since; empty when none")
    summary: BatchSummary | None = Field(None, description="only in GET /batches/{id}")


# --- episodes -------------------------------------------------------------------------------------


class EpisodePublic(BaseModel):
    batch_id: int
    run_index: int
    seed: int
    outcome: str
    passed: bool
    travel_time_s: float | None
    steps: int | None
    time_s: float | None
    min_distance_m: float | None = Field(description="[m] closest distance between the ego's centre and "
                                         "any other road user's centre (centre to centre)")
    min_gap_m: float | None = Field(None, description="[m] closest gap between the ego's footprint and that "
                                    "of a road user it was closing in on (0 or less: touching); null when "
                                    "nobody came close or the episode was recorded before it was kept")
    detail: str
    collided_with: str | None
    events: list[Any]
    error_message: str | None
    wall_s: float | None
    has_trace: bool


# --- live runs ------------------------------------------------------------------------------------

MAX_SUMO_SEED = 2**31 - 1  # SUMO's --seed is a C int


class LiveCreate(BaseModel):
    """One episode of a scenario shown live in the 3D view: a stored scenario (``scenario_id``)
    or one given inline (``scenario``, not stored), a policy and a seed."""

    model_config = _IN

    scenario_id: int | None = Field(None, ge=1, le=MAX_ROW_ID, description="id of a stored scenario")
    scenario: dict[str, Any] | None = Field(None, description="a scenario given inline (not stored)")
    policy: str = Field("rule", min_length=1, max_length=200,
                        description="a policy listed by GET /policies")
    seed: int | None = Field(None, ge=0, le=MAX_SUMO_SEED,
                             description="the episode's seed; default: the seed of the first run of the "
                             "scenario's batches (so the live run replays it)")
    speed: float = Field(1.0, ge=0.0, le=16.0,
                         description="pace: 1 = real time, 2 = twice as fast, 0 = as fast as it runs")


class LivePublic(BaseModel):
    id: int
    scenario: str
    policy: str
    seed: int
    speed: float
    status: Literal["starting", "waiting", "running", "done", "failed", "stopped"] = Field(
        description="starting: building the world; waiting: for a viewer tab (a few seconds at "
        "most); running; then done (see result), failed (see error) or stopped")
    frames: int = Field(description="steps drawn in the viewer so far")
    result: dict[str, Any] | None = Field(None, description="the episode's result once done")
    error: str | None = None
    port: int
    url: str = Field(description="the 3D view: open it in a browser tab")
