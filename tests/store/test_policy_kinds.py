"""ONNX and plugin policies in the store (migration 0004_policy_uploads), on SQLite and PostgreSQL."""

from __future__ import annotations

from pathlib import Path

import pytest
from alembic import command
from sqlalchemy import inspect
from sqlalchemy.exc import IntegrityError

from crossroads.scenario.spec import validate_scenario
from crossroads.store import Store, crud, open_store
from crossroads.store.db import alembic_config, head_revision
from crossroads.store.tables import Policy

BEFORE = "0003_api_hardening"


def _downgrade(store: Store, revision: str) -> None:
    with store.engine.begin() as connection:
        command.downgrade(alembic_config(connection), revision)


def _batch(store: Store, ref: str) -> int:
    spec = validate_scenario({"version": 1, "name": "kinds", "intersection": "a_single_lane", "task": "left",
                              "runs": 2}, check_references=False)
    with store.session() as s:
        scenario = crud.get_or_create_scenario(session=s, spec=spec)
        policy = crud.get_or_create_policy(session=s, ref=ref)
        return crud.create_batch(session=s, scenario=scenario, policy=policy, runs=2).id


def test_onnx_and_plugin_policies_are_stored_and_other_kinds_refused(store: Store, tmp_path: Path) -> None:
    model = tmp_path / "mine.onnx"
    model.write_bytes(b"onnx bytes")
    batch_id = _batch(store, f"onnx:{model}+shield")
    with store.session() as s:
        policy = crud.get_batch(session=s, batch_id=batch_id).policy
        assert (policy.kind, policy.name, policy.ref) == ("onnx", "mine+shield", f"onnx:{model}+shield")
        s.add(Policy(name="x", ref="x", kind="pickle", file_hash="sha256:x"))
        with pytest.raises(IntegrityError):
            s.commit()


def test_the_migration_goes_down_and_up_keeping_the_batches(empty_db_url: str, tmp_path: Path) -> None:
    """With batches referring to policies (so rebuilding the table would fail on SQLite's foreign
    keys), 0004 goes down to 0003 and up again; down is refused while an ONNX policy is stored."""
    with open_store(empty_db_url) as store:
        batch_id = _batch(store, "rule")
        _downgrade(store, BEFORE)
        assert store.revision() == BEFORE
        with store.engine.connect() as conn:
            assert conn.exec_driver_sql("SELECT id FROM batches").all() == [(batch_id,)]
    with open_store(empty_db_url) as store:
        assert store.revision() == head_revision()
        model = tmp_path / "mine.onnx"
        model.write_bytes(b"onnx bytes")
        _batch(store, str(model))
        with pytest.raises(RuntimeError, match="1 ONNX or plugin policies are stored"):
            _downgrade(store, BEFORE)
        assert store.revision() == head_revision()
        assert "policies" in inspect(store.engine).get_table_names()
