"""The search tables on SQLite and the real PostgreSQL: a search, its trials and failures, their
constraints and what deleting a search or a batch does to them."""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy.exc import IntegrityError

from crossroads.scenario.spec import load_scenario
from crossroads.search import records
from crossroads.store import Store, crud, open_store
from crossroads.store.search_tables import SearchTrial
from support import REPO_ROOT

PG_SERVER = os.environ.get("CROSSROADS_TEST_PG", "postgresql+psycopg://postgres@127.0.0.1:5432")
SPEC = load_scenario(REPO_ROOT / "scenarios" / "nominal" / "a_single_lane-left.yaml")


@pytest.fixture(params=["sqlite", "postgresql"])
def store(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Store]:
    if request.param == "sqlite":
        opened = open_store(f"sqlite:///{tmp_path / 'store.db'}")
        yield opened
        opened.close()
        return
    import psycopg

    admin = PG_SERVER.replace("postgresql+psycopg://", "postgresql://") + "/postgres"
    name = f"crossroads_test_{uuid.uuid4().hex[:12]}"
    with psycopg.connect(admin, autocommit=True, connect_timeout=5) as conn:
        conn.execute(f'CREATE DATABASE "{name}"')
    opened = open_store(f"{PG_SERVER}/{name}")
    try:
        yield opened
    finally:
        opened.close()
        with psycopg.connect(admin, autocommit=True, connect_timeout=5) as conn:
            conn.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


def _batch(store: Store) -> int:
    with store.session() as session:
        scenario = crud.get_or_create_scenario(session=session, spec=SPEC)
        policy = crud.get_or_create_policy(session=session, ref="rule")
        return crud.create_batch(session=session, scenario=scenario, policy=policy, runs=1).id


def test_a_search_keeps_its_trials_and_failures(store: Store) -> None:
    batch_id = _batch(store)
    with store.session() as s:
        search = records.create_search(session=s, name="t", policy="rule", space={"version": 1},
                                       sampler="tpe", seed=3, budget=10, generation=2, shrink_steps=4)
        records.start_trial(session=s, search_id=search.id, number=0, kind="search", parent=None,
                            params={"warmup_s": 30.0}, seed=2**40, batch_id=batch_id)
        records.finish_trial(session=s, search_id=search.id, number=0, outcome="collision", objective=-1.0,
                             result={"outcome": "collision", "min_gap_m": -0.1, "events": [1, 2]})
        records.start_trial(session=s, search_id=search.id, number=10, kind="shrink", parent=0,
                            params={"warmup_s": 60.0}, seed=2**40, batch_id=batch_id)
        first = records.record_failure(session=s, search_id=search.id, trial_number=0, minimal_number=0,
                                       outcome="collision", params={"warmup_s": 30.0}, seed=2**40,
                                       spec={"name": "x"}, content_hash="a" * 64, distance=0.5,
                                       off_nominal=["warmup_s"], yaml_path=None)
        again = records.record_failure(session=s, search_id=search.id, trial_number=0, minimal_number=9,
                                       outcome="collision", params={}, seed=1, spec={}, content_hash="b" * 64,
                                       distance=0.0, off_nominal=[], yaml_path=None)
        assert again.id == first.id and again.minimal_number == 0  # recorded once
        records.set_search_status(session=s, search_id=search.id, status="running", workers=2, executor="local")
        search_id = search.id
    with store.session() as s:
        trials = records.trials(session=s, search_id=search_id)
        assert [(t.number, t.kind, t.outcome) for t in trials] == [(0, "search", "collision"), (10, "shrink", None)]
        assert trials[0].seed == 2**40 and trials[0].result == {"outcome": "collision", "min_gap_m": -0.1}
        row = records.get_search(session=s, search_id=search_id)
        assert row is not None and row.status == "running" and row.policy.ref == "rule" and row.started_at
        with pytest.raises(ValueError, match="unknown search status"):
            records.set_search_status(session=s, search_id=search_id, status="paused")
        s.add(SearchTrial(search_id=search_id, number=0, kind="search", params={}, seed=1))
        with pytest.raises(IntegrityError):  # one trial per number
            s.commit()
        s.rollback()
    with store.transaction() as s:  # a deleted batch leaves its trial, without the batch
        crud.delete_batch(session=s, batch_id=batch_id)
    with store.session() as s:
        assert {t.batch_id for t in records.trials(session=s, search_id=search_id)} == {None}
    with store.transaction() as s:  # a deleted search takes its trials and failures along
        row = records.get_search(session=s, search_id=search_id)
        s.delete(row)
    with store.session() as s:
        assert records.trials(session=s, search_id=search_id) == []
        assert records.failures(session=s, search_id=search_id) == []


def test_a_search_needs_a_known_sampler_and_sane_numbers(store: Store) -> None:
    with store.session() as s:
        with pytest.raises(ValueError, match="sampler"):
            records.create_search(session=s, name="t", policy="rule", space={}, sampler="cma",
                                  seed=0, budget=1, generation=1, shrink_steps=0)
        with pytest.raises(IntegrityError):
            records.create_search(session=s, name="t", policy="rule", space={}, sampler="tpe",
                                  seed=0, budget=1, generation=0, shrink_steps=0)
