"""Reports of chosen batches (HTML, CSV) and the paired comparison of any batches picked: the
pass rates with Wilson intervals, exact McNemar on the shared seeds, the per-seed differences."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient

from crossroads.evaluation.metrics import mcnemar_p_value
from crossroads.store import crud


def _batch(client: TestClient, scenario_id: int, outcomes: dict[int, tuple[str, float | None]]) -> int:
    """A batch of the rule policy with these seed → (outcome, travel time) episodes recorded."""
    with client.app.state.store.session() as session:
        batch = crud.create_batch(session=session, scenario=crud.get_scenario(session=session, scenario_id=scenario_id),
                                  policy=crud.get_or_create_policy(session=session, ref="rule"),
                                  runs=len(outcomes), traces="none")
        for k, (seed, (outcome, travel)) in enumerate(outcomes.items()):
            crud.record_episode(session=session, batch_id=batch.id, run_index=k, seed=seed,
                                result={"outcome": outcome, "travel_time_s": travel, "steps": 10, "time_s": 5.0})
        return batch.id


@pytest.fixture(scope="module")
def two_batches(client: TestClient) -> tuple[int, int]:
    from .conftest import TINY_SCENARIO  # noqa: TID252

    sid = client.post("/api/scenarios", json={**TINY_SCENARIO, "name": "compare-me"}).json()["id"]
    a = _batch(client, sid, {1: ("passed", 5.0), 2: ("passed", 6.0), 3: ("collision", None),
                             4: ("passed", 5.5), 5: ("timeout", None), 9: ("passed", 4.0)})
    b = _batch(client, sid, {1: ("passed", 5.5), 2: ("collision", None), 3: ("passed", 7.0),
                             4: ("passed", 5.0), 5: ("passed", 6.5), 8: ("passed", 3.0)})
    return a, b


def test_comparison_of_two_chosen_batches(client: TestClient, two_batches: tuple[int, int]) -> None:
    a, b = two_batches
    body = client.get("/api/reports/comparison", params={"batch": [b, a]}).json()
    first, second = body["batches"]
    assert (first["id"], second["id"]) == (a, b), "in id order"
    assert (first["judged"], first["passed"], second["passed"]) == (6, 4, 5)
    assert first["pass_rate"] == pytest.approx(4 / 6)
    assert first["wilson_low"] < first["pass_rate"] < first["wilson_high"]
    (pair,) = body["pairs"]
    assert (pair["a"], pair["b"], pair["pairs"]) == (a, b, 5), "seeds 1-5 only: 8 and 9 ran in one batch"
    assert (pair["both_passed"], pair["b10"], pair["b01"], pair["both_failed"]) == (2, 1, 2, 0)
    assert pair["p_value"] == pytest.approx(mcnemar_p_value(2, 1)) == 1.0
    seeds = {row["seed"]: row for row in pair["seeds"]}
    assert sorted(seeds) == [1, 2, 3, 4, 5]
    assert seeds[2]["difference"] == "only A passes" and seeds[3]["difference"] == "only B passes"
    assert seeds[1]["travel_time_diff_s"] == pytest.approx(0.5) and seeds[4]["travel_time_diff_s"] == pytest.approx(-0.5)
    assert seeds[5]["travel_time_diff_s"] is None


def test_reports_of_chosen_batches(client: TestClient, two_batches: tuple[int, int]) -> None:
    a, b = two_batches
    html = client.get("/api/reports", params={"batch": [a, b]})
    assert html.status_code == 200 and html.headers["content-type"].startswith("text/html")
    assert "compare-me" in html.text
    csv = client.get("/api/reports", params={"batch": [a, b], "format": "csv"})
    assert csv.status_code == 200 and csv.text.count("compare-me") == 2


@pytest.mark.parametrize("params", [{"batch": [1]}, {"batch": ["x", 2]}, {"batch": list(range(1, 10))}, {}])
def test_a_comparison_needs_two_to_eight_batches(client: TestClient, params: dict[str, Any]) -> None:
    response = client.get("/api/reports/comparison", params=params)
    assert response.status_code == 422 and response.json()["detail"][0]["loc"][:2] == ["query", "batch"], response.text


def test_comparing_an_unknown_batch_is_404(client: TestClient, two_batches: tuple[int, int]) -> None:
    response = client.get("/api/reports/comparison", params={"batch": [two_batches[0], 999_999]})
    assert response.status_code == 404 and "999999" in response.json()["detail"]
