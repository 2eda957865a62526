"""Failure searches: searches, their trials (one batch each) and their shrunk failures.

Revision ID: 0005_search
Revises: 0004_policy_uploads
Create Date: 2026-12-07
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0005_search"
down_revision: str | None = "0004_policy_uploads"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

TZ = sa.DateTime(timezone=True)


def upgrade() -> None:
    op.create_table(
        "searches",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(100), nullable=False),
        sa.Column("policy_id", sa.Integer(), nullable=False),
        sa.Column("space", sa.JSON(), nullable=False),
        sa.Column("sampler", sa.String(16), nullable=False),
        sa.Column("seed", sa.BigInteger(), nullable=False),
        sa.Column("budget", sa.Integer(), nullable=False),
        sa.Column("generation", sa.Integer(), nullable=False),
        sa.Column("shrink_steps", sa.Integer(), nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("failures_dir", sa.Text(), nullable=True),
        sa.Column("executor", sa.String(200), nullable=True),
        sa.Column("workers", sa.Integer(), nullable=True),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column("created_at", TZ, nullable=False),
        sa.Column("started_at", TZ, nullable=True),
        sa.Column("finished_at", TZ, nullable=True),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_searches")),
        sa.ForeignKeyConstraint(["policy_id"], ["policies.id"],
                                name=op.f("fk_searches_policy_id_policies")),
        sa.CheckConstraint(
            "status IN ('queued', 'running', 'done', 'cancelled', 'failed')",
            name=op.f("ck_searches_status")),
        sa.CheckConstraint("sampler IN ('tpe', 'random')", name=op.f("ck_searches_sampler")),
        sa.CheckConstraint("budget >= 0", name=op.f("ck_searches_budget")),
        sa.CheckConstraint("generation >= 1", name=op.f("ck_searches_generation")),
        sa.CheckConstraint("shrink_steps >= 0", name=op.f("ck_searches_shrink_steps")),
    )
    op.create_index(op.f("ix_searches_name"), "searches", ["name"])
    op.create_index(op.f("ix_searches_policy_id"), "searches", ["policy_id"])
    op.create_index(op.f("ix_searches_status"), "searches", ["status"])

    op.create_table(
        "search_trials",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("search_id", sa.Integer(), nullable=False),
        sa.Column("number", sa.Integer(), nullable=False),
        sa.Column("kind", sa.String(8), nullable=False),
        sa.Column("parent", sa.Integer(), nullable=True),
        sa.Column("params", sa.JSON(), nullable=False),
        sa.Column("seed", sa.BigInteger(), nullable=False),
        sa.Column("batch_id", sa.Integer(), nullable=True),
        sa.Column("outcome", sa.String(16), nullable=True),
        sa.Column("objective", sa.Float(), nullable=True),
        sa.Column("result", sa.JSON(), nullable=True),
        sa.Column("created_at", TZ, nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_search_trials")),
        sa.ForeignKeyConstraint(["search_id"], ["searches.id"], ondelete="CASCADE",
                                name=op.f("fk_search_trials_search_id_searches")),
        sa.ForeignKeyConstraint(["batch_id"], ["batches.id"], ondelete="SET NULL",
                                name=op.f("fk_search_trials_batch_id_batches")),
        sa.UniqueConstraint("search_id", "number", name="uq_search_trials_search_number"),
        sa.CheckConstraint("kind IN ('search', 'shrink')", name=op.f("ck_search_trials_kind")),
        sa.CheckConstraint("number >= 0", name=op.f("ck_search_trials_number")),
    )

    op.create_table(
        "search_failures",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("search_id", sa.Integer(), nullable=False),
        sa.Column("trial_number", sa.Integer(), nullable=False),
        sa.Column("minimal_number", sa.Integer(), nullable=False),
        sa.Column("outcome", sa.String(16), nullable=False),
        sa.Column("params", sa.JSON(), nullable=False),
        sa.Column("seed", sa.BigInteger(), nullable=False),
        sa.Column("spec", sa.JSON(), nullable=False),
        sa.Column("content_hash", sa.String(64), nullable=False),
        sa.Column("distance", sa.Float(), nullable=False),
        sa.Column("off_nominal", sa.JSON(), nullable=False),
        sa.Column("yaml_path", sa.Text(), nullable=True),
        sa.Column("created_at", TZ, nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_search_failures")),
        sa.ForeignKeyConstraint(["search_id"], ["searches.id"], ondelete="CASCADE",
                                name=op.f("fk_search_failures_search_id_searches")),
        sa.UniqueConstraint("search_id", "trial_number", name="uq_search_failures_search_trial"),
    )
    op.create_index(op.f("ix_search_failures_content_hash"), "search_failures", ["content_hash"])


def downgrade() -> None:
    op.drop_index(op.f("ix_search_failures_content_hash"), table_name="search_failures")
    op.drop_table("search_failures")
    op.drop_table("search_trials")
    op.drop_index(op.f("ix_searches_status"), table_name="searches")
    op.drop_index(op.f("ix_searches_policy_id"), table_name="searches")
    op.drop_index(op.f("ix_searches_name"), table_name="searches")
    op.drop_table("searches")
