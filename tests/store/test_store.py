"""The results store on SQLite and PostgreSQL: migrations, CRUD helpers, constraints."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import func, inspect, select
from sqlalchemy.exc import IntegrityError

from crossroads.evaluation.episode import EpisodeResult
from crossroads.scenario.spec import ScenarioSpec, content_hash, validate_scenario
from crossroads.store import Store, StoreError, crud, open_store
from crossroads.store.db import alembic_config, head_revision
from crossroads.store.tables import Base, Batch, Episode, Scenario, Trace

TABLES = {"scenarios", "policies", "batches", "episodes", "traces"}


def make_spec(seed: int = 0, name: str = "store-test") -> ScenarioSpec:
    return validate_scenario({"version": 1, "name": name, "intersection": "a_single_lane",
                              "task": "left", "runs": 5, "seed": seed}, check_references=False)


def make_batch(store: Store, *, runs: int = 5, seed: int = 0, warnings: tuple[str, ...] = ()) -> int:
    with store.session() as s:
        scenario = crud.get_or_create_scenario(session=s, spec=make_spec(seed))
        policy = crud.get_or_create_policy(session=s, ref="rule")
        return crud.create_batch(session=s, scenario=scenario, policy=policy, runs=runs,
                                 warnings=warnings).id


def result(outcome: str = "passed", seed: int = 1, **kw: Any) -> EpisodeResult:
    fields: dict[str, Any] = dict(seed=seed, outcome=outcome, steps=80, time_s=8.0,
                                  travel_time_s=3.5 if outcome == "passed" else None,
                                  min_distance_m=4.25, events=[{"t": 0.0, "event": "path", "value": 0}])
    fields.update(kw)
    return EpisodeResult(**fields)


def test_migrations_create_every_table_at_head(store: Store) -> None:
    assert TABLES <= set(inspect(store.engine).get_table_names())
    assert store.revision() == head_revision() is not None
    with store.engine.connect() as conn:  # the migrations build exactly the tables' model
        assert compare_metadata(MigrationContext.configure(conn), Base.metadata) == []


def test_opening_again_is_a_no_op(db_url: str) -> None:
    for _ in range(2):
        with open_store(db_url) as store:
            assert store.revision() == head_revision()


def _downgrade(store: Store, revision: str) -> None:
    with store.engine.begin() as connection:
        command.downgrade(alembic_config(connection), revision)


def test_batch_warnings_migrate_down_and_up_keeping_every_other_row(empty_db_url: str) -> None:
    """0002 adds batches.warnings and its downgrade drops only that column: the batches and their
    episodes stay (SQLite included, where copying the table would cascade to the episodes), and
    opening the store again migrates it back to head, the dropped warnings gone."""
    with open_store(empty_db_url) as store:
        batch_id = make_batch(store, runs=2, seed=21, warnings=("lanes off the paths",))
        with store.session() as s:
            crud.record_episode(session=s, batch_id=batch_id, run_index=0, seed=1, result=result())
        _downgrade(store, "0001_initial")
        assert store.revision() == "0001_initial"
        assert "warnings" not in {c["name"] for c in inspect(store.engine).get_columns("batches")}
        with store.engine.connect() as conn:
            assert conn.exec_driver_sql("SELECT id, runs FROM batches").all() == [(batch_id, 2)]
            assert conn.exec_driver_sql("SELECT batch_id, run_index FROM episodes").all() == [(batch_id, 0)]
    with open_store(empty_db_url) as store:  # a store of before the column: migrated on opening
        assert store.revision() == head_revision()
        with store.engine.connect() as conn:
            assert compare_metadata(MigrationContext.configure(conn), Base.metadata) == []
        with store.session() as s:
            batch = crud.get_batch(session=s, batch_id=batch_id)
            assert batch is not None and batch.warnings is None and batch.runs == 2
            assert crud.done_run_indices(session=s, batch_id=batch_id) == {0}


def test_a_batch_keeps_its_warnings(store: Store) -> None:
    texts = ("cross.net.xml (left from 1si): SUMO's internal lanes run <3.15 m> off", "ünïcode — 2")
    warned = make_batch(store, runs=1, seed=22, warnings=texts)
    quiet = make_batch(store, runs=1, seed=22)
    with store.session() as s:  # a new session: read from the database, not the identity map
        assert crud.get_batch(session=s, batch_id=warned).warnings == list(texts)
        assert crud.get_batch(session=s, batch_id=quiet).warnings is None
        # none is SQL NULL, not the JSON text 'null': a query for batches without warnings finds it
        assert quiet in s.scalars(select(Batch.id).where(Batch.warnings.is_(None))).all()
        assert warned not in s.scalars(select(Batch.id).where(Batch.warnings.is_(None))).all()
        scenario = crud.get_or_create_scenario(session=s, spec=make_spec(22))
        policy = crud.get_or_create_policy(session=s, ref="rule")
        with pytest.raises(TypeError, match="not one string"):
            crud.create_batch(session=s, scenario=scenario, policy=policy, runs=1, warnings="letters")


def test_sqlite_runs_in_wal_mode_with_foreign_keys(tmp_path: Path) -> None:
    with open_store(f"sqlite:///{tmp_path / 'sub' / 'x.db'}") as store, store.engine.connect() as conn:
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
        assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1


def test_unreachable_database_is_a_clear_error() -> None:
    with pytest.raises(StoreError, match="cannot open the store"):
        open_store("postgresql://postgres@127.0.0.1:1/nothing", connect_args={"connect_timeout": 2})


def test_scenarios_and_policies_are_content_addressed(store: Store, tmp_path: Path) -> None:
    with store.session() as s:
        a = crud.get_or_create_scenario(session=s, spec=make_spec(1))
        again = crud.get_or_create_scenario(session=s, spec=make_spec(1))
        other = crud.get_or_create_scenario(session=s, spec=make_spec(2))
        assert a.id == again.id != other.id
        assert a.content_hash == content_hash(make_spec(1)) and a.spec["seed"] == 1
        assert crud.scenario_spec(scenario=a) == make_spec(1)

        rule = crud.get_or_create_policy(session=s, ref="rule")
        assert (rule.kind, rule.file_hash, rule.name) == ("builtin", "builtin:rule", "rule")
        assert crud.get_or_create_policy(session=s, ref="rule").id == rule.id

        ckpt = tmp_path / "apg.pt"
        ckpt.write_bytes(b"weights")
        (tmp_path / "apg.card.json").write_text('{"algorithm": "APG"}')
        p = crud.get_or_create_policy(session=s, ref=str(ckpt))
        assert p.kind == "checkpoint" and p.file_hash.startswith("sha256:") and len(p.file_hash) == 71
        assert p.card == {"algorithm": "APG"} and p.name == "apg"


def test_duplicate_scenario_hash_is_refused(store: Store) -> None:
    spec = make_spec(3)
    with store.session() as s:
        crud.get_or_create_scenario(session=s, spec=spec)
        s.add(Scenario(name="dup", content_hash=content_hash(spec), spec={}))
        with pytest.raises(IntegrityError):
            s.commit()


def test_batch_lifecycle_and_listing(store: Store) -> None:
    batch_id = make_batch(store, runs=3, seed=4)
    with store.session() as s:
        batch = crud.get_batch(session=s, batch_id=batch_id)
        assert batch is not None and batch.status == "queued" and batch.base_seed == 4
        assert batch.scenario.name == "store-test" and batch.policy.ref == "rule"
        running = crud.set_batch_status(session=s, batch_id=batch_id, status="running", workers=2,
                                        executor="local")
        assert running.started_at is not None and running.finished_at is None and running.workers == 2
        done = crud.set_batch_status(session=s, batch_id=batch_id, status="done")
        assert done.finished_at is not None and done.finished_at >= done.started_at
        assert batch_id in [b.id for b in crud.list_batches(session=s, status="done")]
        assert batch_id not in [b.id for b in crud.list_batches(session=s, status="queued")]
        with pytest.raises(ValueError, match="status"):
            crud.set_batch_status(session=s, batch_id=batch_id, status="sleeping")


def test_record_episode_is_idempotent_and_complete(store: Store) -> None:
    batch_id = make_batch(store, seed=5)
    with store.session() as s:
        first = crud.record_episode(session=s, batch_id=batch_id, run_index=0, seed=11,
                                    result=result(seed=11), wall_s=0.5)
        assert first is not None
        # the same run again (a resumed batch, a second runner): not recorded, not counted
        assert crud.record_episode(session=s, batch_id=batch_id, run_index=0, seed=11,
                                   result=result("collision", seed=11)) is None
        crud.record_episode(session=s, batch_id=batch_id, run_index=2, seed=13,
                            result=result("timeout", seed=13, min_distance_m=math.inf))
        crud.record_episode(session=s, batch_id=batch_id, run_index=1, seed=12,
                            error="SumoError: connection lost",
                            trace=crud.TraceRef(size_bytes=3, sha256="0" * 64, path="/t/1.trace.npz"))
        assert crud.done_run_indices(session=s, batch_id=batch_id) == {0, 1, 2}
        assert crud.outcome_counts(session=s, batch_id=batch_id) == {"passed": 1, "timeout": 1, "error": 1}
        rows = crud.batch_results(session=s, batch_id=batch_id)
        assert [r.run_index for r in rows] == [0, 1, 2]
        assert rows[0].outcome == "passed" and rows[0].travel_time_s == 3.5
        assert rows[0].events[0]["event"] == "path"
        assert rows[1].error_message == "SumoError: connection lost"
        assert rows[1].trace.path == "/t/1.trace.npz"
        assert rows[2].min_distance_m is None  # nobody around: no distance, not infinity
        with pytest.raises(ValueError):
            crud.record_episode(session=s, batch_id=batch_id, run_index=3, seed=1)


def test_episode_unique_per_batch_and_run(store: Store) -> None:
    batch_id = make_batch(store, seed=6)
    with store.session() as s:
        crud.record_episode(session=s, batch_id=batch_id, run_index=0, seed=1, result=result())
        s.add(Episode(batch_id=batch_id, run_index=0, seed=1, outcome="passed", detail="", events=[]))
        with pytest.raises(IntegrityError):
            s.commit()
        s.rollback()
        assert s.scalar(select(func.count()).select_from(Episode).where(Episode.batch_id == batch_id)) == 1


def test_constraints_hold(store: Store) -> None:
    batch_id = make_batch(store, seed=7)
    with store.session() as s:
        s.add(Episode(batch_id=batch_id, run_index=0, seed=1, outcome="flying", detail="", events=[]))
        with pytest.raises(IntegrityError):
            s.commit()
        s.rollback()
        s.add(Episode(batch_id=987654, run_index=0, seed=1, outcome="passed", detail="", events=[]))
        with pytest.raises(IntegrityError):  # foreign keys are enforced (SQLite too)
            s.commit()


def test_a_failed_episode_write_leaves_nothing_behind(store: Store) -> None:
    with store.session() as s:
        traces_before = s.scalar(select(func.count()).select_from(Trace))
        with pytest.raises(IntegrityError):  # no such batch: the trace row must not stay either
            crud.record_episode(session=s, batch_id=987654, run_index=0, seed=1, result=result(),
                                trace=crud.TraceRef(size_bytes=1, sha256="f" * 64, path="/x"))
        s.rollback()
        assert s.scalar(select(func.count()).select_from(Trace)) == traces_before


def test_paired_results_match_seeds(store: Store) -> None:
    a, b = make_batch(store, seed=8), make_batch(store, seed=8)
    with store.session() as s:
        for batch_id, outcome in ((a, "passed"), (b, "collision")):
            for i in range(3):
                crud.record_episode(session=s, batch_id=batch_id, run_index=i, seed=100 + i,
                                    result=result(outcome, seed=100 + i))
        pairs = crud.paired_results(session=s, batch_a=a, batch_b=b)
        assert [(x.seed, x.outcome, y.outcome) for x, y in pairs] == [
            (100 + i, "passed", "collision") for i in range(3)]
        assert crud.delete_batch(session=s, batch_id=b)
        assert crud.batch_results(session=s, batch_id=b) == []


def test_cancel_requests_migrate_down_and_up_keeping_every_other_row(empty_db_url: str) -> None:
    """0003 adds batches.cancel_requested_at; its downgrade drops only that column (the batch and
    its episodes stay), and opening the store again brings it back, empty."""
    with open_store(empty_db_url) as store:
        batch_id = make_batch(store, runs=2, seed=31)
        with store.session() as s:
            crud.record_episode(session=s, batch_id=batch_id, run_index=0, seed=1, result=result())
            crud.request_cancel(session=s, batch_id=batch_id)
        _downgrade(store, "0002_batch_warnings")
        assert store.revision() == "0002_batch_warnings"
        assert "cancel_requested_at" not in {c["name"] for c in inspect(store.engine).get_columns("batches")}
        with store.engine.connect() as conn:
            assert conn.exec_driver_sql("SELECT batch_id, run_index FROM episodes").all() == [(batch_id, 0)]
    with open_store(empty_db_url) as store:
        assert store.revision() == head_revision()
        with store.session() as s:
            batch = crud.get_batch(session=s, batch_id=batch_id)
            assert batch is not None and batch.cancel_requested_at is None and batch.status == "queued"


def test_a_cancel_request_is_stored_and_ends_the_batch_at_restart(store: Store) -> None:
    """request_cancel writes at once (the first time counts); a restart's end_requested_cancels
    marks the unfinished ones cancelled and unfinished_batches no longer offers them."""
    asked, running, other = (make_batch(store, runs=1, seed=s) for s in (41, 42, 43))
    with store.session() as s:
        crud.set_batch_status(session=s, batch_id=running, status="running")
        first = crud.request_cancel(session=s, batch_id=asked).cancel_requested_at
        assert first is not None
    with store.session() as s:  # read back (SQLite keeps no time zone: compare the naive times)
        again = crud.request_cancel(session=s, batch_id=asked).cancel_requested_at
        assert again.replace(tzinfo=None) == first.replace(tzinfo=None)
        crud.request_cancel(session=s, batch_id=running)
        assert crud.request_cancel(session=s, batch_id=10**6) is None
    mine = {asked, running, other}  # (the PostgreSQL database is shared by the session's tests)
    with store.session() as s:
        assert [b.id for b in crud.unfinished_batches(session=s) if b.id in mine] == [other]
        assert mine & set(crud.end_requested_cancels(session=s)) == {asked, running}
        assert not mine & set(crud.end_requested_cancels(session=s))
    with store.session() as s:
        for batch_id in (asked, running):
            batch = crud.get_batch(session=s, batch_id=batch_id)
            assert batch.status == "cancelled" and batch.finished_at is not None
        assert crud.get_batch(session=s, batch_id=other).status == "queued"


@pytest.mark.parametrize("big", [2**31, 2**63 - 1, 2**63, 10**30, 0, -1])
def test_ids_beyond_the_columns_find_nothing(store: Store, big: int) -> None:
    """An id the INTEGER columns cannot hold (32-bit on PostgreSQL, 64-bit on SQLite) never reaches
    the driver: it finds nothing instead of raising."""
    batch_id = make_batch(store, runs=1, seed=51)
    with store.session() as s:
        assert crud.get_batch(session=s, batch_id=big) is None
        assert crud.get_scenario(session=s, scenario_id=big) is None
        assert crud.get_policy(session=s, policy_id=big) is None
        assert crud.get_episode(session=s, batch_id=big, run_index=0) is None
        assert crud.get_episode(session=s, batch_id=batch_id, run_index=big if big else -1) is None
        assert crud.batch_results(session=s, batch_id=big) == []
        assert crud.count_results(session=s, batch_id=big) == 0
        assert crud.list_batches(session=s, scenario_id=big) == []
        assert crud.count_batches(session=s, scenario_id=big) == 0
        assert crud.delete_batch(session=s, batch_id=big) is False
        assert crud.request_cancel(session=s, batch_id=big) is None


def test_batches_are_bounded_in_runs(store: Store) -> None:
    with store.session() as s:
        scenario = crud.get_or_create_scenario(session=s, spec=make_spec(61))
        policy = crud.get_or_create_policy(session=s, ref="rule")
        for runs in (0, 10_001, 10**12):
            with pytest.raises(ValueError, match="runs must be in 1..10000"):
                crud.create_batch(session=s, scenario=scenario, policy=policy, runs=runs)
        assert crud.create_batch(session=s, scenario=scenario, policy=policy, runs=10_000).runs == 10_000


def test_scenarios_are_listed_in_pages(store: Store) -> None:
    with store.session() as s:
        ids = [crud.get_or_create_scenario(session=s, spec=make_spec(70 + i)).id for i in range(3)]
        total = crud.count_scenarios(session=s)
        assert total >= 3
        listed = [r.id for r in crud.list_scenarios(session=s, limit=total)]
        assert listed == sorted(listed) and set(ids) <= set(listed)
        assert [r.id for r in crud.list_scenarios(session=s, limit=2, offset=1)] == listed[1:3]
        batch = crud.create_batch(session=s, scenario=crud.get_scenario(session=s, scenario_id=ids[0]),
                                  policy=crud.get_or_create_policy(session=s, ref="rule"), runs=1)
        assert crud.batch_counts(session=s, scenario_ids=ids) == {ids[0]: 1}
        assert crud.count_batches(session=s, scenario_id=ids[0]) == 1 and batch.id
