"""The results store's tables of failure searches (``crossroads search``).

searches ─< search_trials >─ batches (each trial is one stored batch of one run);
searches ─< search_failures (each a shrunk failure: a scenario in the failures collection).

A search is resumable from these rows alone: the space (nominal scenario inline), the sampler and
its seed, the budget; a trial is ``(search_id, number)``, unique, recorded when its episode has
been; ``kind`` says whether the optimiser proposed it (``search``) or shrinking did (``shrink``,
with ``parent``: the number of the search trial it shrinks).

Part of the same metadata as :mod:`crossroads.store.tables` (imported with the package), and
created by migration ``0005_search``.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import (
    JSON,
    BigInteger,
    CheckConstraint,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import Mapped, mapped_column, relationship

from crossroads.store.tables import Base, Batch, Policy, _in, utcnow

SEARCH_STATUSES = ("queued", "running", "done", "cancelled", "failed")
SAMPLERS = ("tpe", "random")
TRIAL_KINDS = ("search", "shrink")


class Search(Base):
    """One search of a space for a policy's failures."""

    __tablename__ = "searches"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(100), index=True)  # the space's name
    policy_id: Mapped[int] = mapped_column(ForeignKey("policies.id"), index=True)
    space: Mapped[dict[str, Any]] = mapped_column(JSON)  # the space, nominal scenario inline
    sampler: Mapped[str] = mapped_column(String(16))  # tpe | random
    seed: Mapped[int] = mapped_column(BigInteger)
    budget: Mapped[int] = mapped_column(Integer)  # episodes the optimiser proposes
    generation: Mapped[int] = mapped_column(Integer)  # trials proposed at once
    shrink_steps: Mapped[int] = mapped_column(Integer)  # at most this many episodes per failure
    status: Mapped[str] = mapped_column(String(16), default="queued", index=True)
    failures_dir: Mapped[str | None] = mapped_column(Text, nullable=True)  # the YAML collection
    executor: Mapped[str | None] = mapped_column(String(200), nullable=True)  # local | ray:<address>
    workers: Mapped[int | None] = mapped_column(Integer, nullable=True)
    error: Mapped[str | None] = mapped_column(Text, nullable=True)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)

    __table_args__ = (
        CheckConstraint(_in("status", SEARCH_STATUSES), name="status"),
        CheckConstraint(_in("sampler", SAMPLERS), name="sampler"),
        CheckConstraint("budget >= 0", name="budget"),
        CheckConstraint("generation >= 1", name="generation"),
        CheckConstraint("shrink_steps >= 0", name="shrink_steps"),
    )

    policy: Mapped[Policy] = relationship()
    trials: Mapped[list[SearchTrial]] = relationship(
        back_populates="search", order_by="SearchTrial.number", passive_deletes=True)
    failures: Mapped[list[SearchFailure]] = relationship(
        back_populates="search", order_by="SearchFailure.trial_number", passive_deletes=True)


class SearchTrial(Base):
    """One episode of a search: where in the space, its batch, and how it came out."""

    __tablename__ = "search_trials"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    search_id: Mapped[int] = mapped_column(ForeignKey("searches.id", ondelete="CASCADE"))
    number: Mapped[int] = mapped_column(Integer)
    kind: Mapped[str] = mapped_column(String(8))  # search | shrink
    parent: Mapped[int | None] = mapped_column(Integer, nullable=True)  # shrink: the failure's trial
    params: Mapped[dict[str, Any]] = mapped_column(JSON)  # parameter path → value
    seed: Mapped[int] = mapped_column(BigInteger)  # the scenario's base seed
    batch_id: Mapped[int | None] = mapped_column(
        ForeignKey("batches.id", ondelete="SET NULL"), nullable=True)
    outcome: Mapped[str | None] = mapped_column(String(16), nullable=True)  # None: not run yet
    objective: Mapped[float | None] = mapped_column(Float, nullable=True)  # None: crashed / not run
    result: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)  # EpisodeResult JSON
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)

    __table_args__ = (
        UniqueConstraint("search_id", "number", name="uq_search_trials_search_number"),
        CheckConstraint(_in("kind", TRIAL_KINDS), name="kind"),
        CheckConstraint("number >= 0", name="number"),
    )

    search: Mapped[Search] = relationship(back_populates="trials")
    batch: Mapped[Batch | None] = relationship()


class SearchFailure(Base):
    """A failure the search found, shrunk: a minimal failing scenario with its seed."""

    __tablename__ = "search_failures"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    search_id: Mapped[int] = mapped_column(ForeignKey("searches.id", ondelete="CASCADE"))
    trial_number: Mapped[int] = mapped_column(Integer)  # the search trial that found it
    minimal_number: Mapped[int] = mapped_column(Integer)  # the trial that ran the minimal scenario
    outcome: Mapped[str] = mapped_column(String(16))
    params: Mapped[dict[str, Any]] = mapped_column(JSON)  # the minimal scenario's parameters
    seed: Mapped[int] = mapped_column(BigInteger)
    spec: Mapped[dict[str, Any]] = mapped_column(JSON)  # its ScenarioSpec (JSON)
    content_hash: Mapped[str] = mapped_column(String(64), index=True)
    distance: Mapped[float] = mapped_column(Float)  # from nominal, in parameter ranges
    off_nominal: Mapped[list[Any]] = mapped_column(JSON)  # the parameters still moved
    yaml_path: Mapped[str | None] = mapped_column(Text, nullable=True)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)

    __table_args__ = (
        UniqueConstraint("search_id", "trial_number", name="uq_search_failures_search_trial"),
    )

    search: Mapped[Search] = relationship(back_populates="failures")
