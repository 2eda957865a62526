"""Policies may be ONNX files and Python plugins: ``policies.kind`` admits ``onnx`` and ``plugin``.

Uploaded ONNX policies themselves are files (``<data_dir>/policies/<name>.onnx`` with their card
beside), like uploaded networks; the store only learns of one when a batch runs it.

Revision ID: 0004_policy_uploads
Revises: 0003_api_hardening
Create Date: 2026-12-06
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0004_policy_uploads"
down_revision: str | None = "0003_api_hardening"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

OLD = "kind IN ('builtin', 'checkpoint')"
NEW = "kind IN ('builtin', 'checkpoint', 'onnx', 'plugin')"


def _sqlite_check(old: str, new: str) -> None:
    """Swap the CHECK text in SQLite's schema. Why not batch mode: rebuilding ``policies`` drops
    the old table, and with foreign keys on (they are, inside this transaction) that fails as soon
    as a batch refers to a policy. A change that only relaxes a CHECK constraint leaves every stored
    row valid, which is the case SQLite documents for editing the schema text in place
    (sqlite.org/lang_altertable.html, "Making Other Kinds Of Table Schema Changes")."""
    bind = op.get_bind()
    sql = bind.exec_driver_sql("SELECT sql FROM sqlite_master WHERE type = 'table' AND name = 'policies'").scalar_one()
    if old not in sql:
        raise RuntimeError(f"policies table: expected the constraint {old!r} in {sql!r}")
    version = bind.exec_driver_sql("PRAGMA schema_version").scalar_one()
    bind.exec_driver_sql("PRAGMA writable_schema = ON")
    try:
        bind.exec_driver_sql("UPDATE sqlite_master SET sql = ? WHERE type = 'table' AND name = 'policies'",
                             (sql.replace(old, new),))
        bind.exec_driver_sql(f"PRAGMA schema_version = {int(version) + 1}")
    finally:
        bind.exec_driver_sql("PRAGMA writable_schema = OFF")


def upgrade() -> None:
    if op.get_bind().dialect.name == "sqlite":
        _sqlite_check(OLD, NEW)
        return
    op.drop_constraint(op.f("ck_policies_kind"), "policies", type_="check")
    op.create_check_constraint(op.f("ck_policies_kind"), "policies", sa.text(NEW))


def downgrade() -> None:
    # Refused while ONNX or plugin policies are stored: narrowing the constraint would leave them invalid.
    bind = op.get_bind()
    newer = bind.exec_driver_sql("SELECT COUNT(*) FROM policies WHERE kind IN ('onnx', 'plugin')").scalar_one()
    if newer:
        raise RuntimeError(f"{newer} ONNX or plugin policies are stored; delete their batches and "
                           "policies before downgrading below 0004_policy_uploads")
    if bind.dialect.name == "sqlite":
        _sqlite_check(NEW, OLD)
        return
    op.drop_constraint(op.f("ck_policies_kind"), "policies", type_="check")
    op.create_check_constraint(op.f("ck_policies_kind"), "policies", sa.text(OLD))
