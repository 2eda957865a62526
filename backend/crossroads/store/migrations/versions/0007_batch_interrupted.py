"""Batches say when a server stopped under them: status ``interrupted`` and ``batches.heartbeat_at``.

``heartbeat_at``: when the API process that runs (or queues) the batch last said it still does; it
writes it every few seconds. A batch left ``queued`` or ``running`` whose heartbeat has gone stale
was abandoned by a process that stopped (killed, crashed): the API marks it ``interrupted`` rather
than show it running forever, and a user resumes it (POST /batches/{id}/resume). A graceful
shutdown marks its batches ``interrupted`` itself. Batches run by ``crossroads evaluate`` have no
heartbeat (NULL) and are never judged by it.

Revision ID: 0007_batch_interrupted
Revises: 0006_episode_gap
Create Date: 2026-12-07
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0007_batch_interrupted"
down_revision: str | None = "0006_episode_gap"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

OLD = "status IN ('queued', 'running', 'done', 'cancelled', 'failed')"
NEW = "status IN ('queued', 'running', 'done', 'cancelled', 'failed', 'interrupted')"


def _sqlite_check(old: str, new: str) -> None:
    """Swap the CHECK text in SQLite's schema of ``batches`` (as 0004_policy_uploads does for
    ``policies``: rebuilding the table in batch mode would cascade to the episodes). Widening a
    CHECK leaves every stored row valid, the case SQLite documents for editing the schema text."""
    bind = op.get_bind()
    sql = bind.exec_driver_sql("SELECT sql FROM sqlite_master WHERE type = 'table' AND name = 'batches'").scalar_one()
    if old not in sql:
        raise RuntimeError(f"batches table: expected the constraint {old!r} in {sql!r}")
    version = bind.exec_driver_sql("PRAGMA schema_version").scalar_one()
    bind.exec_driver_sql("PRAGMA writable_schema = ON")
    try:
        bind.exec_driver_sql("UPDATE sqlite_master SET sql = ? WHERE type = 'table' AND name = 'batches'",
                             (sql.replace(old, new),))
        bind.exec_driver_sql(f"PRAGMA schema_version = {int(version) + 1}")
    finally:
        bind.exec_driver_sql("PRAGMA writable_schema = OFF")


def upgrade() -> None:
    # Nullable: batches recorded before, and those of `crossroads evaluate`, have no heartbeat.
    op.add_column("batches", sa.Column("heartbeat_at", sa.DateTime(timezone=True), nullable=True))
    if op.get_bind().dialect.name == "sqlite":
        _sqlite_check(OLD, NEW)
        return
    op.drop_constraint(op.f("ck_batches_status"), "batches", type_="check")
    op.create_check_constraint(op.f("ck_batches_status"), "batches", sa.text(NEW))


def downgrade() -> None:
    # An interrupted batch goes back to ``queued`` (what a stopped server left before 0007).
    bind = op.get_bind()
    bind.exec_driver_sql("UPDATE batches SET status = 'queued' WHERE status = 'interrupted'")
    if bind.dialect.name == "sqlite":
        _sqlite_check(NEW, OLD)
    else:
        op.drop_constraint(op.f("ck_batches_status"), "batches", type_="check")
        op.create_check_constraint(op.f("ck_batches_status"), "batches", sa.text(OLD))
    # A plain DROP COLUMN, not batch mode (see 0002_batch_warnings: a copy would cascade).
    op.drop_column("batches", "heartbeat_at")
