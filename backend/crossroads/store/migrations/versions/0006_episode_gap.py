"""Episodes keep their closest footprint gap: ``episodes.min_gap_m``.

The smallest gap between the ego's outline and that of a road user it was closing in on (0 or
less: touching), as the episode result gives it (``EpisodeResult.min_gap_m``); the centre-to-centre
``min_distance_m`` stays beside it. Episodes recorded before have none (NULL).

Revision ID: 0006_episode_gap
Revises: 0005_search
Create Date: 2026-12-07
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0006_episode_gap"
down_revision: str | None = "0005_search"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column("episodes", sa.Column("min_gap_m", sa.Float(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("episodes") as batch:
        batch.drop_column("min_gap_m")
