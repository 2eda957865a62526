"""Batches keep the warnings their network gave when they were created (``batches.warnings``).

Revision ID: 0002_batch_warnings
Revises: 0001_initial
Create Date: 2026-12-05
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0002_batch_warnings"
down_revision: str | None = "0001_initial"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # A nullable column: existing batches read as "no warnings" (their network was not measured).
    op.add_column("batches", sa.Column("warnings", sa.JSON(), nullable=True))


def downgrade() -> None:
    # A plain ALTER TABLE ... DROP COLUMN (SQLite >= 3.35 has it), not batch mode: batch mode would
    # copy and drop the batches table, and with foreign keys on, SQLite's DROP TABLE deletes its
    # rows first, which cascades to every episode.
    op.drop_column("batches", "warnings")
