"""The initial schema: scenarios, policies, batches, traces, episodes.

Revision ID: 0001_initial
Revises:
Create Date: 2025-11-23
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0001_initial"
down_revision: str | None = None
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

TZ = sa.DateTime(timezone=True)


def upgrade() -> None:
    op.create_table(
        "scenarios",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(100), nullable=False),
        sa.Column("content_hash", sa.String(64), nullable=False),
        sa.Column("spec", sa.JSON(), nullable=False),
        sa.Column("created_at", TZ, nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_scenarios")),
        sa.UniqueConstraint("content_hash", name=op.f("uq_scenarios_content_hash")),
    )
    op.create_index(op.f("ix_scenarios_name"), "scenarios", ["name"])

    op.create_table(
        "policies",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("ref", sa.String(1000), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("file_hash", sa.String(80), nullable=False),
        sa.Column("card", sa.JSON(), nullable=True),
        sa.Column("created_at", TZ, nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_policies")),
        sa.UniqueConstraint("file_hash", name=op.f("uq_policies_file_hash")),
        sa.CheckConstraint("kind IN ('builtin', 'checkpoint')", name=op.f("ck_policies_kind")),
    )

    op.create_table(
        "batches",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("scenario_id", sa.Integer(), nullable=False),
        sa.Column("policy_id", sa.Integer(), nullable=False),
        sa.Column("runs", sa.Integer(), nullable=False),
        sa.Column("base_seed", sa.BigInteger(), nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("traces", sa.String(8), nullable=False),
        sa.Column("base_dir", sa.Text(), nullable=True),
        sa.Column("executor", sa.String(200), nullable=True),
        sa.Column("workers", sa.Integer(), nullable=True),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column("created_at", TZ, nullable=False),
        sa.Column("started_at", TZ, nullable=True),
        sa.Column("finished_at", TZ, nullable=True),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_batches")),
        sa.ForeignKeyConstraint(["scenario_id"], ["scenarios.id"],
                                name=op.f("fk_batches_scenario_id_scenarios")),
        sa.ForeignKeyConstraint(["policy_id"], ["policies.id"],
                                name=op.f("fk_batches_policy_id_policies")),
        sa.CheckConstraint(
            "status IN ('queued', 'running', 'done', 'cancelled', 'failed')",
            name=op.f("ck_batches_status")),
        sa.CheckConstraint("traces IN ('all', 'failed', 'none')", name=op.f("ck_batches_traces")),
        sa.CheckConstraint("runs >= 1", name=op.f("ck_batches_runs")),
    )
    op.create_index(op.f("ix_batches_scenario_id"), "batches", ["scenario_id"])
    op.create_index(op.f("ix_batches_policy_id"), "batches", ["policy_id"])
    op.create_index(op.f("ix_batches_status"), "batches", ["status"])

    op.create_table(
        "traces",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("path", sa.Text(), nullable=True),
        sa.Column("blob", sa.LargeBinary(), nullable=True),
        sa.Column("size_bytes", sa.BigInteger(), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("created_at", TZ, nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_traces")),
        sa.CheckConstraint("path IS NOT NULL OR blob IS NOT NULL", name=op.f("ck_traces_location")),
    )

    op.create_table(
        "episodes",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("batch_id", sa.Integer(), nullable=False),
        sa.Column("run_index", sa.Integer(), nullable=False),
        sa.Column("seed", sa.BigInteger(), nullable=False),
        sa.Column("outcome", sa.String(16), nullable=False),
        sa.Column("travel_time_s", sa.Float(), nullable=True),
        sa.Column("steps", sa.Integer(), nullable=True),
        sa.Column("time_s", sa.Float(), nullable=True),
        sa.Column("min_distance_m", sa.Float(), nullable=True),
        sa.Column("detail", sa.Text(), nullable=False),
        sa.Column("collided_with", sa.String(16), nullable=True),
        sa.Column("events", sa.JSON(), nullable=False),
        sa.Column("error_message", sa.Text(), nullable=True),
        sa.Column("wall_s", sa.Float(), nullable=True),
        sa.Column("trace_id", sa.Integer(), nullable=True),
        sa.Column("created_at", TZ, nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_episodes")),
        sa.ForeignKeyConstraint(["batch_id"], ["batches.id"], ondelete="CASCADE",
                                name=op.f("fk_episodes_batch_id_batches")),
        sa.ForeignKeyConstraint(["trace_id"], ["traces.id"], ondelete="SET NULL",
                                name=op.f("fk_episodes_trace_id_traces")),
        sa.UniqueConstraint("batch_id", "run_index", name="uq_episodes_batch_run"),
        sa.CheckConstraint(
            "outcome IN ('passed', 'collision', 'red_light', 'off_road', 'timeout', 'error')",
            name=op.f("ck_episodes_outcome")),
        sa.CheckConstraint("run_index >= 0", name=op.f("ck_episodes_run_index")),
    )
    op.create_index(op.f("ix_episodes_outcome"), "episodes", ["outcome"])


def downgrade() -> None:
    op.drop_table("episodes")
    op.drop_table("traces")
    op.drop_table("batches")
    op.drop_table("policies")
    op.drop_index(op.f("ix_scenarios_name"), table_name="scenarios")
    op.drop_table("scenarios")
