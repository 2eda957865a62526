"""Property-based fuzzing of the whole API (schemathesis over its OpenAPI schema): every operation,
with requests that fit the schema and requests that do not, sent in process (ASGI) to the real app
on SQLite and on PostgreSQL. No answer may be a server error.

The store starts with one scenario and one finished batch of one episode (its trace kept), so that
the ids the fuzzer tries first (1, 0) reach real rows. Requests that start work do start it (real
batch runners, real SUMO children); so that a generated batch never becomes a long one, every batch
the fuzzer gets accepted is cancelled at once, every live run stopped, and the app runs one batch at
a time with a short per-episode wall-clock limit. Hypothesis is derandomized: the same requests
every run.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import time
from collections import Counter

import pytest
import schemathesis
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis.errors import Unsatisfiable
from schemathesis import GenerationMode
from schemathesis.python import asgi

from crossroads.api.deps import ApiOptions
from crossroads.api.main import create_app
from crossroads.settings import Settings

from .conftest import TINY_SCENARIO  # noqa: TID252

EXAMPLES = 12  # per operation and generation mode
MIN_REQUESTS = 500  # per database: over both, at least 1 000
READ_TIMEOUT_S = 10.0  # an event stream of a batch that is still cancelling is cut here
SEED_BATCH_TIMEOUT_S = 120.0


@pytest.fixture(params=["sqlite", "postgresql"])
def fuzz_app(request: pytest.FixtureRequest, tmp_path: Path, models_dir: Path) -> Iterator[Any]:
    """A fresh app on an empty database of its own; its lifespan ends with the test."""
    if request.param == "postgresql":
        from store.pg import fresh_pg_database

        with fresh_pg_database() as url:
            yield from _app(tmp_path, url, models_dir)
    else:
        yield from _app(tmp_path, f"sqlite:///{tmp_path / 'fuzz.db'}", models_dir)


def _app(tmp_path: Path, url: str, models_dir: Path) -> Iterator[Any]:
    settings = Settings(data_dir=tmp_path / "data", db_url=url, allowed_hosts=(asgi.HOST,),
                        max_concurrent_batches=1, max_batch_workers=1, episode_wall_limit_s=20.0,
                        resume_batches=False)
    app = create_app(settings, ApiOptions(upload_max_bytes=64 * 1024, models_dir=models_dir))
    try:
        yield app
    finally:
        asgi.shutdown_lifespans()  # stops the batches and live runs, closes the store


def _client(app: Any) -> Any:
    client = asgi.get_client(app)
    client.base_url = f"http://{asgi.HOST}"
    return client


def _seed(app: Any) -> None:
    """One stored scenario and one finished batch of one episode, its trace kept."""
    client = _client(app)
    scenario = client.post("/api/scenarios", json=TINY_SCENARIO)
    assert scenario.status_code == 201, scenario.text
    batch = client.post("/api/batches", json={"scenario_id": scenario.json()["id"], "runs": 1, "workers": 1,
                                              "traces": "all"})
    assert batch.status_code == 202, batch.text
    deadline = time.monotonic() + SEED_BATCH_TIMEOUT_S
    while (status := client.get(batch.json()["url"]).json()["status"]) not in ("done", "failed", "cancelled"):
        assert time.monotonic() < deadline, status
        time.sleep(0.2)
    assert status == "done"


def _stop_what_started(case: Any, response: Any) -> None:
    """Whatever a POST started in the background (a 202 naming an id: a batch, a live run, a
    search, ...) is cancelled or stopped at once."""
    if response.status_code != 202 or case.method != "POST":
        return
    started = response.json()
    if not isinstance(started, dict) or "id" not in started:
        return
    client = _client(case.operation.app)
    for action in ("cancel", "stop"):
        if client.post(f"{case.formatted_path}/{started['id']}/{action}").status_code not in (404, 405):
            return


@pytest.mark.slow
def test_no_request_is_a_server_error(fuzz_app: Any) -> None:
    schema = schemathesis.openapi.from_asgi("/openapi.json", fuzz_app)  # starts the app's lifespan
    _seed(fuzz_app)
    operations = [result.ok() for result in schema.get_all_operations()]
    assert len(operations) >= 30, [f"{o.method} {o.path}" for o in operations]
    sent: list[str] = []
    failures: list[str] = []
    for operation in operations:
        for mode in (GenerationMode.POSITIVE, GenerationMode.NEGATIVE):

            @settings(max_examples=EXAMPLES, deadline=None, database=None, derandomize=True,
                      phases=[Phase.explicit, Phase.generate], suppress_health_check=list(HealthCheck))
            @given(case=operation.as_strategy(generation_mode=mode))
            def call(case: Any) -> None:
                response = case.call(timeout=READ_TIMEOUT_S)
                sent.append(f"{case.method} {case.path} {response.status_code}")
                if response.status_code >= 500:
                    failures.append(f"{response.status_code} for {case.as_curl_command()}: {response.text[:300]}")
                _stop_what_started(case, response)

            try:
                call()
            except Unsatisfiable:  # nothing of this operation can break its schema (it has no input)
                assert mode == GenerationMode.NEGATIVE, f"{operation.method} {operation.path}"
    assert not failures, "\n".join(failures[:10])
    assert len(sent) >= MIN_REQUESTS, f"only {len(sent)} requests"
    answered = Counter(s.rsplit(" ", 1)[1] for s in sent)
    print(f"{len(sent)} requests, 0 server errors; answers: {dict(sorted(answered.items()))}")
