"""What a batch keeps of its network's warnings (evaluation/network_checks.py)."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from crossroads.evaluation import network_checks
from crossroads.evaluation.network_checks import batch_warnings, internal_lane_warning, network_problems
from crossroads.evaluation.scenario import ScenarioSpec, validate_scenario
from crossroads.planning.routes import PlanningError
from support import SUMO_CROSS_NET, sumo_example


def left_turn(intersection: str | dict[str, str]) -> ScenarioSpec:
    return validate_scenario({"version": 1, "name": "checked-left", "intersection": intersection,
                              "task": "left"}, check_references=False)


def test_a_batch_on_a_net_whose_internal_lanes_run_off_the_paths_keeps_the_warning(tmp_path: Path) -> None:
    """SUMO's example cross.net.xml: netconvert's left turns run up to 3.1 m from the candidate
    paths. The net has no problems (a batch may run on it), and the batch keeps the one warning
    `crossroads evaluate` prints, relative net paths resolved against base_dir as the world does."""
    net = sumo_example(SUMO_CROSS_NET)
    spec = left_turn({"net": str(net)})
    assert network_problems(spec) == []
    warnings = batch_warnings(spec)
    assert warnings == [internal_lane_warning(spec)]
    assert "cross.net.xml (left from" in warnings[0] and "crossroads net check" in warnings[0]

    (tmp_path / "cross.net.xml").write_bytes(net.read_bytes())
    assert batch_warnings(left_turn({"net": "cross.net.xml"}), tmp_path) == warnings


def test_a_batch_on_a_catalogue_net_keeps_none() -> None:
    """The catalogue's builds draw every internal lane along its candidate path."""
    assert batch_warnings(left_turn("c_three_lane")) == []


def test_a_network_that_cannot_be_measured_still_gets_its_batch(monkeypatch: pytest.MonkeyPatch,
                                                                 caplog: pytest.LogCaptureFixture) -> None:
    """A degenerate shape makes the measurement raise ValueError (PlanningError, JunctionError): the
    batch is created without the warning, and the log says why. No real net found here raises it
    (single-point, repeated-point and NaN internal lanes all measure), so the measurement is
    replaced by one that raises, as PlanningError would."""
    def degenerate(spec: ScenarioSpec, base_dir: object = None) -> str | None:
        raise PlanningError("lane 'x' has a zero-length shape")

    monkeypatch.setattr(network_checks, "internal_lane_warning", degenerate)
    with caplog.at_level(logging.WARNING, logger=network_checks.log.name):
        assert batch_warnings(left_turn("c_three_lane")) == []
    assert "could not measure the internal lanes" in caplog.text and "zero-length shape" in caplog.text


def test_anything_but_an_odd_shape_is_raised(monkeypatch: pytest.MonkeyPatch) -> None:
    """Only ValueError is taken for an odd shape: a bug elsewhere is not hidden as 'no warning'."""
    def broken(spec: ScenarioSpec, base_dir: object = None) -> str | None:
        raise KeyError("lanes")

    monkeypatch.setattr(network_checks, "internal_lane_warning", broken)
    with pytest.raises(KeyError):
        batch_warnings(left_turn("c_three_lane"))
