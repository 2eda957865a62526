"""A search end to end: real SUMO episodes through the batch workers, the store, shrinking, the
failures collection, its replay with `crossroads evaluate`, resuming, and the report."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

from crossroads.search import records
from crossroads.search.engine import SearchError, SearchRunner, summarize_search
from crossroads.search.space import load_space, seed_pool
from crossroads.store import open_store
from support import REPO_ROOT

pytestmark = pytest.mark.slow

NOMINAL = REPO_ROOT / "scenarios" / "nominal" / "a_single_lane-left.yaml"


def crossroads(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "CROSSROADS_DATA_DIR": str(cwd / "data")}  # traces stay in the test's folder
    return subprocess.run([sys.executable, "-m", "crossroads.cli", *args], capture_output=True,
                          text=True, cwd=cwd, env=env, timeout=600)


def write_space(tmp_path: Path) -> Path:
    """Short episodes; every point is the ego 3–6 m before the line at 9–10 m/s on red (the cross
    street's green): a red-light run whatever the driver, so the test does not hang on luck. The
    sampler chooses the seed too, among three."""
    scenario = yaml.safe_load(NOMINAL.read_text())
    scenario.update(warmup_s=5.0, timeout_s=15.0, runs=1)
    space = {
        "version": 1, "name": "red", "scenario": scenario,
        "parameters": [
            {"path": "lights.phase", "choices": [4]},
            {"path": "ego.start_distance_m", "low": 3.0, "high": 6.0},
            {"path": "ego.start_speed_mps", "low": 9.0, "high": 10.0},
        ],
        "seed": {"low": 0, "high": 1000, "pool": 3},
    }
    path = tmp_path / "space.yaml"
    path.write_text(yaml.safe_dump(space))
    return path


def test_a_search_finds_shrinks_stores_and_replays_its_failures(tmp_path: Path) -> None:
    space = write_space(tmp_path)
    db = f"sqlite:///{tmp_path / 'search.db'}"
    failures_dir = tmp_path / "failures"
    report = tmp_path / "report.html"
    done = crossroads("search", "rule", "--space", str(space), "--budget", "2", "--workers", "2",
                      "--db", db, "--seed", "4", "--failures-dir", str(failures_dir), "--shrink-limit", "1",
                      "--report", str(report), "--json", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    summary: dict[str, Any] = json.loads(done.stdout.splitlines()[0])
    assert summary["status"] == "done" and summary["searched"] == 2
    assert summary["outcomes"] == {"red_light": 2} and summary["failing"] == 2
    assert summary["failures"] == summary["distinct_failures"] == 2
    assert 0 < summary["shrink_episodes"] <= 6
    pool = seed_pool(load_space(space), 4)
    assert pool is not None and {f["seed"] for f in summary["failure_list"]} <= set(pool)
    shrunk, kept = summary["failure_list"]
    # the start speed is not what makes it fail: shrinking took it back to nominal (8.33 m/s)
    assert "ego.start_speed_mps" not in shrunk["off_nominal"] and "lights.phase" in shrunk["off_nominal"]
    assert shrunk["minimal_trial"] >= 2  # a shrinking episode's scenario
    # beyond --shrink-limit 1: kept as found
    assert kept["minimal_trial"] == kept["trial"] and len(kept["off_nominal"]) == 3
    assert "kept as found" in (failures_dir / f"{kept['name']}.yaml").read_text()
    assert {f["outcome"] for f in summary["failure_list"]} == {"red_light"}
    files = sorted(failures_dir.glob("*.yaml"))
    assert [f.name for f in files] == sorted(f"{f['name']}.yaml" for f in summary["failure_list"])
    text = report.read_text()
    assert "data:image/png;base64," in text and summary["failure_list"][0]["name"] in text

    # every stored failure replays with the same outcome through `crossroads evaluate`
    replay_db = f"sqlite:///{tmp_path / 'replay.db'}"
    for path in files:
        replay = crossroads("evaluate", str(path), "--policy", "rule", "--db", replay_db, "--workers", "1",
                            "--json", cwd=tmp_path)
        assert replay.returncode == 0, replay.stderr
        [batch] = json.loads(replay.stdout.splitlines()[-1])
        assert batch["runs"] == 1 and batch["outcome_counts"]["red_light"] == 1, batch

    # resuming a finished search runs nothing more
    again = crossroads("search", "--resume", str(summary["search_id"]), "--db", db, "--json", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert json.loads(again.stdout.splitlines()[0])["shrink_episodes"] == summary["shrink_episodes"]

    # an interrupted search resumes where it stopped, proposing the same points again
    store = open_store(db)
    try:
        with store.transaction() as session:
            rows = records.trials(session=session, search_id=summary["search_id"])
            last_search = max(t.number for t in rows if t.kind == "search")
            proposed = next(t.params for t in rows if t.number == last_search)
            for row in rows:
                if row.number == last_search or row.parent == last_search:
                    session.delete(row)
            for row in records.failures(session=session, search_id=summary["search_id"]):
                if row.trial_number == last_search:
                    session.delete(row)
        resumed = SearchRunner(store, summary["search_id"], workers=1, data_dir=tmp_path / "data").run()
        assert resumed["searched"] == 2 and resumed["failures"] == 2
        with store.session() as session:
            rerun = next(t for t in records.trials(session=session, search_id=summary["search_id"])
                         if t.number == last_search)
        assert rerun.params == proposed and rerun.outcome == "red_light"
        # stored trials that disagree with what the sampler proposes are refused, not mixed
        with store.transaction() as session:
            row = next(t for t in records.trials(session=session, search_id=summary["search_id"])
                       if t.number == 0)
            proposed_first, proposed_seed = dict(row.params), row.seed
            assert proposed_seed in pool
            row.params = {**row.params, "ego.start_distance_m": 5.123456}
            row.outcome = None
        with pytest.raises(SearchError, match="trial 0 was stored with"):
            SearchRunner(store, summary["search_id"], workers=1, data_dir=tmp_path / "data").run()
        assert summarize_search(store, summary["search_id"])["status"] == "failed"
        with store.transaction() as session:  # the same parameters, another seed than the pool's choice
            row = next(t for t in records.trials(session=session, search_id=summary["search_id"])
                       if t.number == 0)
            row.params, row.seed = dict(proposed_first), row.seed + 1
        with pytest.raises(SearchError, match=f"seed {proposed_seed + 1}, the sampler now proposes"):
            SearchRunner(store, summary["search_id"], workers=1, data_dir=tmp_path / "data").run()
    finally:
        store.close()


def test_a_bad_space_or_policy_fails_before_anything_runs(tmp_path: Path) -> None:
    space = write_space(tmp_path)
    data = yaml.safe_load(space.read_text())
    data["parameters"][0] = {"path": "lights.phase", "choices": [4, 40]}
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    db = f"sqlite:///{tmp_path / 'search.db'}"
    result = crossroads("search", "rule", "--space", str(bad), "--budget", "1", "--db", db, cwd=tmp_path)
    assert result.returncode == 2 and "parameters.0" in result.stderr and "lights.phase" in result.stderr
    result = crossroads("search", "models/none.pt", "--space", str(space), "--budget", "1", "--db", db,
                        cwd=tmp_path)
    assert result.returncode == 2 and "does not exist" in result.stderr
    result = crossroads("search", "rule", "--budget", "1", "--db", db, cwd=tmp_path)
    assert result.returncode != 0 and "--space" in result.stderr
    store = open_store(db)
    try:
        with store.session() as session:
            assert records.list_searches(session=session) == []
    finally:
        store.close()


def write_mixed_space(tmp_path: Path) -> Path:
    """Short episodes; the light at entry is the ego's green (phase 0: a pass or a timeout) or the
    cross street's (phase 4, the ego 3–6 m before the line at 9–10 m/s: a red-light run)."""
    path = write_space(tmp_path)
    data = yaml.safe_load(path.read_text())
    data["name"] = "mixed"
    data["parameters"][0] = {"path": "lights.phase", "choices": [0, 4]}
    path.write_text(yaml.safe_dump(data))
    return path


# The fields of a trial's result that an episode's row in the results store keeps too.
EPISODE_FIELDS = ("outcome", "steps", "time_s", "travel_time_s", "min_distance_m", "min_gap_m", "detail",
                  "collided_with")


def test_trials_on_the_pool_are_those_of_batch_workers_and_replay_with_crossroads_evaluate(tmp_path: Path) -> None:
    """The same search on the search's long-lived workers (2 at once) and with a fresh batch worker
    per trial (1 at once): the same points, seeds and results, trial for trial. Then `crossroads
    evaluate` on every stored failure gives its trial's episode again, field for field."""
    from crossroads.search.engine import create_search_for
    from crossroads.store import crud

    space = load_space(write_mixed_space(tmp_path))
    store = open_store(f"sqlite:///{tmp_path / 'search.db'}")
    try:
        searched: dict[str, list[tuple[Any, ...]]] = {}
        ids: dict[str, int] = {}
        for executor, workers in (("pool", 2), ("batch", 1)):
            search_id = create_search_for(store, space=space, policy="rule", budget=6, seed=11, generation=2,
                                          shrink_steps=0, failures_dir=tmp_path / f"failures-{executor}")
            summary = SearchRunner(store, search_id, workers=workers, data_dir=tmp_path / "data",
                                   executor=executor).run()
            assert summary["status"] == "done" and summary["searched"] == 6, summary
            ids[executor] = search_id
            with store.session() as session:
                rows = records.trials(session=session, search_id=search_id, kind="search")
                searched[executor] = [(t.number, t.params, t.seed, t.result) for t in rows]
                executors = {crud.get_batch(session=session, batch_id=t.batch_id).executor for t in rows}
            assert executors == {"local (search pool)" if executor == "pool" else "local"}
        assert searched["pool"] == searched["batch"]
        outcomes = {result["outcome"] for *_, result in searched["pool"]}
        assert "red_light" in outcomes and outcomes - {"red_light"}, outcomes  # failures and not
        by_name = {f"mixed-s{ids['pool']}-t{number}": result for number, _, _, result in searched["pool"]}
    finally:
        store.close()

    files = sorted((tmp_path / "failures-pool").glob("*.yaml"))
    assert len(files) == sum(result["outcome"] == "red_light" for result in by_name.values())
    replay_db = f"sqlite:///{tmp_path / 'replay.db'}"
    replay = crossroads("evaluate", str(tmp_path / "failures-pool"), "--policy", "rule", "--db", replay_db,
                        "--workers", "2", "--json", cwd=tmp_path)
    assert replay.returncode == 0, replay.stderr
    replays = open_store(replay_db)
    try:
        with replays.session() as session:
            batches = crud.list_batches(session=session, limit=100)
            assert len(batches) == len(files)
            for batch in batches:
                (episode,) = crud.batch_results(session=session, batch_id=batch.id)
                trial = by_name[batch.scenario.name]
                assert {k: getattr(episode, k) for k in EPISODE_FIELDS} == {k: trial[k] for k in EPISODE_FIELDS}
    finally:
        replays.close()
