"""Batch evaluation end to end on a tiny scenario: local processes, Ray, crashes, resume, CLI."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from crossroads.cli import app
from crossroads.evaluation.batch import BatchRunner, create_batch_for, summarize_batch
from crossroads.scenario.spec import ScenarioSpec, load_scenario, run_seeds
from crossroads.store import Store, crud, open_store

TINY = {  # a short, quiet episode: ~90 steps, a fraction of a second
    "version": 1, "name": "tiny-left", "intersection": "a_single_lane", "task": "left",
    "traffic": {"vehicles_per_hour": 100, "cyclists_per_hour": 0, "pedestrians_per_hour": 0},
    "warmup_s": 5.0, "timeout_s": 12.0, "runs": 4, "seed": 7,
}


@pytest.fixture
def scenario_file(tmp_path: Path) -> Path:
    path = tmp_path / "tiny-left.yaml"
    path.write_text(yaml.safe_dump(TINY))
    return path


@pytest.fixture
def spec(scenario_file: Path) -> ScenarioSpec:
    return load_scenario(scenario_file)


@pytest.fixture
def store(tmp_path: Path) -> Iterator[Store]:
    opened = open_store(f"sqlite:///{tmp_path / 'results.db'}")
    yield opened
    opened.close()


def episodes(store: Store, batch_id: int) -> list[Any]:
    with store.session() as s:
        return crud.batch_results(session=s, batch_id=batch_id)


def test_batch_records_every_run_with_its_seed_and_trace(store: Store, spec: ScenarioSpec,
                                                          tmp_path: Path) -> None:
    batch_id = create_batch_for(store, spec=spec, policy="rule", traces="all")
    calls: list[tuple[int, int]] = []
    result = BatchRunner(store, batch_id, workers=2, data_dir=tmp_path,
                         on_progress=lambda done, total, last: calls.append((done, total))).run()
    assert result.status == "done" and result.recorded == result.runs == 4 and result.errors == 0
    assert calls[0] == (0, 4) and calls[-1] == (4, 4) and len(calls) == 5
    rows = episodes(store, batch_id)
    assert [r.run_index for r in rows] == [0, 1, 2, 3]
    assert [r.seed for r in rows] == run_seeds(spec, 4)
    assert sum(r.outcome == "passed" for r in rows) == result.passed
    for r in rows:
        path = tmp_path / "traces" / str(batch_id) / f"{r.run_index}.trace.npz"
        assert r.trace is not None and r.trace.path == str(path)
        assert hashlib.sha256(path.read_bytes()).hexdigest() == r.trace.sha256
    with store.session() as s:
        batch = crud.get_batch(session=s, batch_id=batch_id)
        assert batch.workers == 2 and batch.executor == "local" and batch.finished_at is not None


def test_crashed_episode_and_killed_worker_are_errors_and_the_batch_goes_on(
        store: Store, spec: ScenarioSpec, tmp_path: Path) -> None:
    batch_id = create_batch_for(store, spec=spec, policy="rule", runs=6, traces="failed")
    result = BatchRunner(store, batch_id, workers=2, data_dir=tmp_path,
                         faults={1: "raise", 3: "kill"}).run()
    assert result.status == "done" and result.recorded == 6 and result.errors == 2
    assert result.judged == 4 and result.pass_rate == result.passed / 4
    rows = {r.run_index: r for r in episodes(store, batch_id)}
    assert rows[1].outcome == "error" and rows[1].error_message.startswith("RuntimeError: injected fault")
    assert rows[1].trace is not None  # the partial trace of the crash, for replay
    assert rows[3].outcome == "error" and "SIGKILL" in rows[3].error_message.splitlines()[0]
    assert all(rows[i].outcome != "error" for i in (0, 2, 4, 5))
    assert all((rows[i].trace is None) == (rows[i].outcome == "passed") for i in (0, 2, 4, 5))


def test_cancelled_batch_resumes_without_running_or_counting_twice(
        store: Store, spec: ScenarioSpec, tmp_path: Path) -> None:
    batch_id = create_batch_for(store, spec=spec, policy="rule", runs=6, traces="none")
    first: BatchRunner

    def stop_after_two(done: int, total: int, last: Any) -> None:
        if done >= 2:
            first.cancel()

    first = BatchRunner(store, batch_id, workers=2, data_dir=tmp_path, on_progress=stop_after_two)
    first.start()  # the API's way: in the background
    interrupted = first.wait(timeout=60)
    assert interrupted is not None and interrupted.status == "cancelled"
    assert 2 <= interrupted.recorded < 6
    before = {r.run_index: (r.id, r.outcome) for r in episodes(store, batch_id)}

    reported: list[int] = []
    second = BatchRunner(store, batch_id, workers=2, data_dir=tmp_path,
                         on_progress=lambda d, t, last: last and reported.append(last.run_index))
    resumed = second.run()
    assert resumed.status == "done" and resumed.recorded == 6
    assert sorted(reported) == sorted(set(range(6)) - set(before))  # only the missing runs ran
    rows = episodes(store, batch_id)
    assert [r.run_index for r in rows] == list(range(6))
    assert all((r.id, r.outcome) == before[r.run_index] for r in rows if r.run_index in before)
    assert second.progress.done == 6 == second.progress.total


def test_two_policies_meet_the_same_seeds(store: Store, spec: ScenarioSpec, tmp_path: Path) -> None:
    ckpt = tmp_path / "other.pt"  # registered as a second policy; it is not run here
    ckpt.write_bytes(b"not yet trained")
    a = create_batch_for(store, spec=spec, policy="rule", runs=3)
    b = create_batch_for(store, spec=spec, policy=str(ckpt), runs=3)
    BatchRunner(store, a, workers=1, data_dir=tmp_path).run()
    seeds = run_seeds(spec, 3)
    assert [r.seed for r in episodes(store, a)] == seeds
    with store.session() as s:
        batch_b = crud.get_batch(session=s, batch_id=b)
        assert batch_b.policy_id != crud.get_batch(session=s, batch_id=a).policy_id
        assert run_seeds(crud.scenario_spec(scenario=batch_b.scenario).model_copy(
            update={"seed": batch_b.base_seed}), batch_b.runs) == seeds


@pytest.mark.slow
def test_local_ray_executor(store: Store, spec: ScenarioSpec, tmp_path: Path) -> None:
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        batch_id = create_batch_for(store, spec=spec, policy="rule", runs=2, traces="failed")
        result = BatchRunner(store, batch_id, workers=2, ray_address="local", data_dir=tmp_path,
                             faults={1: "raise"}).run()
    finally:
        ray.shutdown()
    assert result.status == "done" and result.recorded == 2 and result.errors == 1
    rows = episodes(store, batch_id)
    assert rows[0].outcome != "error" and rows[1].error_message.startswith("RuntimeError")
    with store.session() as s:
        assert crud.get_batch(session=s, batch_id=batch_id).executor == "ray:local"


def test_cli_evaluate_json(scenario_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CROSSROADS_DATA_DIR", str(tmp_path / "data"))
    db = f"sqlite:///{tmp_path / 'cli.db'}"
    out = CliRunner().invoke(app, ["evaluate", str(scenario_file), "--policy", "rule", "--runs", "2",
                                   "--workers", "1", "--db", db, "--json", "--traces", "none"])
    assert out.exit_code == 0, out.output
    (batch,) = json.loads(out.stdout)
    assert batch["runs"] == 2 and batch["recorded"] == 2 and batch["errors"] == 0
    assert batch["scenario"] == "tiny-left" and batch["policy"] == "rule"
    assert 0.0 <= batch["wilson_low"] <= batch["wilson_high"] <= 1.0
    assert sum(batch["outcome_counts"].values()) == 2
    assert batch["warnings"] == []  # the catalogue's internal lanes follow the paths
    with open_store(db) as store:
        assert summarize_batch(store, batch["batch_id"]).recorded == 2

    text = CliRunner().invoke(app, ["evaluate", "--resume", str(batch["batch_id"]), "--db", db])
    assert text.exit_code == 0 and f"batch {batch['batch_id']}: tiny-left x rule [done]" in text.stdout

    assert "warning" not in text.stderr  # the catalogue's internal lanes follow the paths
    bad = CliRunner().invoke(app, ["evaluate", str(scenario_file), "--policy", "missing.pt", "--db", db])
    assert bad.exit_code == 2 and "missing.pt" in bad.output

    report = tmp_path / "report.html"
    table = tmp_path / "report.csv"
    made = CliRunner().invoke(app, ["report", str(batch["batch_id"]), "--db", db, "-o", str(report),
                                    "--csv", str(table)])
    assert made.exit_code == 0, made.output
    html = report.read_text()
    assert "tiny-left" in html and "data:image/png;base64," in html
    assert "<h2>Warnings</h2>" not in html  # nothing stored for a catalogue net
    assert table.read_text().count("\n") == 2  # header + one batch
    missing = CliRunner().invoke(app, ["report", "999", "--db", db, "-o", str(report)])
    assert missing.exit_code == 2 and "no batch 999" in missing.output


def test_cli_evaluate_checks_the_network_before_any_batch(tmp_path: Path) -> None:
    """A field only the network contradicts (a lane that is not on the approach) stops the
    command with the field named, before a batch is stored or an episode runs."""
    path = tmp_path / "bad-lane.yaml"
    path.write_text(yaml.safe_dump({**TINY, "name": "bad-lane", "ego": {"entrance_lane": "nope_0"}}))
    db = f"sqlite:///{tmp_path / 'cli.db'}"
    out = CliRunner().invoke(app, ["evaluate", str(path), "--policy", "rule", "--runs", "2",
                                   "--workers", "1", "--db", db])
    assert out.exit_code == 2 and "ego.entrance_lane" in out.output and "'nope_0'" in out.output
    with open_store(db) as store, store.session() as s:
        assert crud.list_batches(session=s) == []


def test_cli_evaluate_warns_when_the_egos_internal_lanes_run_off_its_paths(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """SUMO's example cross.net.xml, netconvert's lanes: the left turns' internal lanes run up to
    3.1 m from the paper's candidate paths (ρ = 0.6). The batch runs, with a warning naming the net
    and the movement."""
    from support import SUMO_CROSS_NET, sumo_example

    monkeypatch.setenv("CROSSROADS_DATA_DIR", str(tmp_path / "data"))
    path = tmp_path / "cross-left.yaml"
    path.write_text(yaml.safe_dump({**TINY, "name": "cross-left", "rho": 0.6,
                                    "intersection": {"net": str(sumo_example(SUMO_CROSS_NET))}}))
    db = f"sqlite:///{tmp_path / 'cli.db'}"
    out = CliRunner().invoke(app, ["evaluate", str(path), "--policy", "rule", "--runs", "1", "--workers", "1",
                                   "--db", db, "--traces", "none"])
    assert out.exit_code == 0, out.output
    assert "warning:" in out.stderr and "cross.net.xml (left from" in out.stderr
    assert "crossroads net check" in out.stderr and "cross-left x rule" in out.stdout
    # the batch keeps the warning it printed, and its reports show it, read whenever they are
    printed = out.stderr.split(f"warning: {path}: ", 1)[1].splitlines()[0]
    with open_store(db) as store, store.session() as s:
        (batch,) = crud.list_batches(session=s)
        assert batch.warnings == [printed]
        assert summarize_batch(store, batch.id).warnings == [printed]  # what --json prints
    report, markdown = tmp_path / "report.html", tmp_path / "report.md"
    made = CliRunner().invoke(app, ["report", str(batch.id), "--db", db, "-o", str(report),
                                    "--markdown", str(markdown)])
    assert made.exit_code == 0, made.output
    assert "<h2>Warnings</h2>" in report.read_text() and "cross.net.xml (left from" in report.read_text()
    assert f"- batch {batch.id} (cross-left, rule): {printed}" in markdown.read_text()


def test_a_batch_keeps_the_warning_its_network_gave_when_it_was_created(
        store: Store, spec: ScenarioSpec, tmp_path: Path) -> None:
    """A batch on cross.net.xml (netconvert's left turns up to 3.1 m off the paper's candidate
    paths, the net given relative to base_dir) stores the warning; one on a catalogue net stores none."""
    from support import SUMO_CROSS_NET, sumo_example

    (tmp_path / "cross.net.xml").write_bytes(sumo_example(SUMO_CROSS_NET).read_bytes())
    path = tmp_path / "cross-left.yaml"
    path.write_text(yaml.safe_dump({**TINY, "name": "cross-left", "rho": 0.6, "intersection": {"net": "cross.net.xml"}}))
    flagged = create_batch_for(store, spec=load_scenario(path), policy="rule", runs=1, base_dir=path.parent)
    catalogue = create_batch_for(store, spec=spec, policy="rule", runs=1)
    with store.session() as s:
        (warning,) = crud.get_batch(session=s, batch_id=flagged).warnings
        assert warning.startswith("cross.net.xml (left from") and "crossroads net check" in warning
        assert crud.get_batch(session=s, batch_id=catalogue).warnings is None
