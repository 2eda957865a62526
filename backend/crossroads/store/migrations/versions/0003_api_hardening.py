"""Batches remember a cancel as soon as it is asked for (``batches.cancel_requested_at``).

Revision ID: 0003_api_hardening
Revises: 0002_batch_warnings
Create Date: 2026-12-06
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0003_api_hardening"
down_revision: str | None = "0002_batch_warnings"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # Nullable: existing batches were never asked to cancel (or their cancel has already ended them).
    op.add_column("batches", sa.Column("cancel_requested_at", sa.DateTime(timezone=True), nullable=True))


def downgrade() -> None:
    # A plain DROP COLUMN, not batch mode: copying the batches table on SQLite would cascade to the
    # episodes (see 0002_batch_warnings).
    op.drop_column("batches", "cancel_requested_at")
