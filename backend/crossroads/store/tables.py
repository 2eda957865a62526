"""The results store's tables (SQLAlchemy 2, typed declarative).

scenarios ─< batches >─ policies;  batches ─< episodes >─ traces (optional, one per episode).

Identity: a scenario is its :func:`~crossroads.scenario.spec.content_hash` (the canonical
spec JSON is stored beside it); a policy is its ``file_hash`` (``sha256:<hex>`` of a checkpoint
file, ``builtin:rule`` for a built-in). An episode is ``(batch_id, run_index)``: unique, so a
resumed batch can never record a run twice.

Every schema change goes through a migration in ``migrations/versions`` (``open_store`` applies
them); this module is the model the migrations are written against.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    BigInteger,
    CheckConstraint,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship

# Stable constraint names: Alembic can then alter them on every backend (SQLite batch mode too).
NAMING_CONVENTION = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}

BATCH_STATUSES = ("queued", "running", "done", "cancelled", "failed", "interrupted")
EPISODE_OUTCOMES = ("passed", "collision", "red_light", "off_road", "timeout", "error")
TRACE_MODES = ("all", "failed", "none")
POLICY_KINDS = ("builtin", "checkpoint", "onnx", "plugin")  # how a policy is identified (crossroads.policy.identity)
MAX_ROW_ID = 2**31 - 1  # ids and run indices are INTEGER columns: 32-bit on PostgreSQL


def utcnow() -> datetime:
    return datetime.now(UTC)


def _in(column: str, values: tuple[str, ...]) -> str:
    return f"{column} IN ({', '.join(repr(v) for v in values)})"


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING_CONVENTION)
    type_annotation_map = {dict[str, Any]: JSON, list[Any]: JSON}


class Scenario(Base):
    """A scenario spec as evaluated (content-addressed)."""

    __tablename__ = "scenarios"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(100), index=True)
    content_hash: Mapped[str] = mapped_column(String(64), unique=True)  # sha256 hex of canonical JSON
    spec: Mapped[dict[str, Any]] = mapped_column(JSON)  # ScenarioSpec.model_dump(mode="json")
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)

    batches: Mapped[list[Batch]] = relationship(back_populates="scenario")


class Policy(Base):
    """A driver: a built-in (``rule``), a trained checkpoint, an ONNX file or a Python plugin,
    identified by its content (``crossroads.policy.identity``)."""

    __tablename__ = "policies"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(200))  # e.g. "rule", "apg"
    ref: Mapped[str] = mapped_column(String(1000))  # what was given: "rule", "models/apg.pt"
    kind: Mapped[str] = mapped_column(String(16))  # builtin | checkpoint | onnx | plugin
    file_hash: Mapped[str] = mapped_column(String(80), unique=True)  # sha256:<hex> | builtin:<name>
    card: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)  # model card
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)

    __table_args__ = (CheckConstraint(_in("kind", POLICY_KINDS), name="kind"),)

    batches: Mapped[list[Batch]] = relationship(back_populates="policy")


class Batch(Base):
    """N seeded runs of one scenario with one policy."""

    __tablename__ = "batches"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    scenario_id: Mapped[int] = mapped_column(ForeignKey("scenarios.id"), index=True)
    policy_id: Mapped[int] = mapped_column(ForeignKey("policies.id"), index=True)
    runs: Mapped[int] = mapped_column(Integer)
    base_seed: Mapped[int] = mapped_column(BigInteger)  # run seeds: run_seeds(spec with this seed)
    status: Mapped[str] = mapped_column(String(16), default="queued", index=True)
    traces: Mapped[str] = mapped_column(String(8), default="failed")  # all | failed | none
    base_dir: Mapped[str | None] = mapped_column(Text, nullable=True)  # resolves relative net paths
    executor: Mapped[str | None] = mapped_column(String(200), nullable=True)  # local | ray:<address>
    workers: Mapped[int | None] = mapped_column(Integer, nullable=True)
    error: Mapped[str | None] = mapped_column(Text, nullable=True)  # why the batch failed
    # What the network gave reason to warn about when the batch was created (e.g. SUMO's internal
    # lanes off the ego's paths), kept with it: a report read later must say it, whatever the network
    # has become. None is SQL NULL (none_as_null), not JSON null: "no warnings" reads one way.
    warnings: Mapped[list[str] | None] = mapped_column(JSON(none_as_null=True), nullable=True)
    # When a user asked to cancel the batch: written at once, before any runner has stopped, so the
    # cancel survives a restart (a batch with it set is never resumed, whatever its status says).
    cancel_requested_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    # When the API process running (or queueing) the batch last said it still does (every few
    # seconds): a stale one on an unfinished batch means that process stopped (status then
    # ``interrupted``). None: never run by the API (e.g. `crossroads evaluate`), or before 0007.
    heartbeat_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)

    __table_args__ = (
        CheckConstraint(_in("status", BATCH_STATUSES), name="status"),
        CheckConstraint(_in("traces", TRACE_MODES), name="traces"),
        CheckConstraint("runs >= 1", name="runs"),
    )

    scenario: Mapped[Scenario] = relationship(back_populates="batches")
    policy: Mapped[Policy] = relationship(back_populates="batches")
    episodes: Mapped[list[Episode]] = relationship(
        back_populates="batch", order_by="Episode.run_index", passive_deletes=True)


class Trace(Base):
    """An episode's trace: a ``.trace.npz`` file on disk (``path``) or its bytes (``blob``)."""

    __tablename__ = "traces"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    path: Mapped[str | None] = mapped_column(Text, nullable=True)
    blob: Mapped[bytes | None] = mapped_column(LargeBinary, nullable=True)
    size_bytes: Mapped[int] = mapped_column(BigInteger)
    sha256: Mapped[str] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)

    __table_args__ = (CheckConstraint("path IS NOT NULL OR blob IS NOT NULL", name="location"),)


class Episode(Base):
    """One run of a batch: its result, or ``outcome = 'error'`` with the message."""

    __tablename__ = "episodes"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    batch_id: Mapped[int] = mapped_column(ForeignKey("batches.id", ondelete="CASCADE"))
    run_index: Mapped[int] = mapped_column(Integer)
    seed: Mapped[int] = mapped_column(BigInteger)
    outcome: Mapped[str] = mapped_column(String(16), index=True)
    travel_time_s: Mapped[float | None] = mapped_column(Float, nullable=True)  # [s] passed only
    steps: Mapped[int | None] = mapped_column(Integer, nullable=True)
    time_s: Mapped[float | None] = mapped_column(Float, nullable=True)  # [s] ego time
    min_distance_m: Mapped[float | None] = mapped_column(Float, nullable=True)  # [m] None: nobody
    # [m] closest footprint gap to one closing in (<= 0: touching); None: nobody, or recorded before 0006
    min_gap_m: Mapped[float | None] = mapped_column(Float, nullable=True)
    detail: Mapped[str] = mapped_column(Text, default="")
    collided_with: Mapped[str | None] = mapped_column(String(16), nullable=True)
    events: Mapped[list[Any]] = mapped_column(JSON, default=list)
    error_message: Mapped[str | None] = mapped_column(Text, nullable=True)
    wall_s: Mapped[float | None] = mapped_column(Float, nullable=True)  # [s] wall-clock of the run
    trace_id: Mapped[int | None] = mapped_column(
        ForeignKey("traces.id", ondelete="SET NULL"), nullable=True)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)

    __table_args__ = (
        UniqueConstraint("batch_id", "run_index", name="uq_episodes_batch_run"),
        CheckConstraint(_in("outcome", EPISODE_OUTCOMES), name="outcome"),
        CheckConstraint("run_index >= 0", name="run_index"),
    )

    batch: Mapped[Batch] = relationship(back_populates="episodes")
    trace: Mapped[Trace | None] = relationship()

    @property
    def passed(self) -> bool:
        return self.outcome == "passed"
