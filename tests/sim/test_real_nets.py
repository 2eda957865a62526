"""Any SUMO intersection, for real (issue 36): the corpus of benchmarks/real_nets.py, checked.

Every traffic-light junction with three or more car approaches of ../shared/realnets, of the
example nets inside the eclipse-sumo wheel and of four nets built here (a T junction with a
bike-less approach and a short last edge, five legs, a divided road's joined pair of nodes, a
light with two programs): every approach × task either has candidates a car can drive or is
refused in one line. Every walk the demand may draw for a pedestrian is one SUMO routes. Then a
few seeded episodes per task on a selection of them, with the rule controller and SUMO's own
driver: no ``error`` outcome, no collision before t = 2 s. The full corpus at 20 seeds is
``benchmarks/real_nets.py`` (its figures: docs/results/real-nets.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from crossroads.idc.rule_based import RuleBasedController
from crossroads.network.junction import read_junction
from crossroads.planning import PlanningError, plan_task
from crossroads.planning.curves import MAX_CURVATURE
from crossroads.planning.drivable import road_check
from crossroads.sim.sumo import SumoSession
from crossroads.scenario.spec import to_world_config
from crossroads.sim.traffic import DemandPlan, Departure, walkable_pairs, write_plan
from crossroads.sim.world import World
from support import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "benchmarks"))
from real_nets import EARLY_COLLISION_S, Case, check_paths, corpus, run_case, scenario_for  # noqa: E402

# The episodes' selection: the real nets written by others, every net built here, and a few of
# the wheel's (an OSM city cut, a compressed net, a game net with one static program per stage,
# the RiLSA example), one junction each. Two seeds of the rule controller, one of SUMO's
# driver, 10 s each (the errors of the issue came at the start or once the light cycled past a
# program's end, which the 60 s warm-up covers).
EPISODE_CASES = ("cologne1", "sumo-rl", "gen-tee3", "gen-star5", "gen-joined", "gen-programs",
                 "sumo-cross/cross", "sumo-fkk_in/ingolstadt", "sumo-bs3d/bs",
                 "sumo-RiLSA_example1/net", "sumo-DRT/osm:3246050928")
SEEDS = {"rule": 2, "sumo": 1}
EPISODE_TIMEOUT_S = 10.0


@pytest.fixture(scope="module")
def cases(tmp_path_factory: pytest.TempPathFactory) -> list[Case]:
    return corpus(tmp_path_factory.mktemp("corpus"))


def test_the_corpus_covers_what_the_issue_names(cases: list[Case]) -> None:
    names = [c.name for c in cases]
    assert len(cases) >= 45, names
    for prefix in ("cologne1", "sumo-rl", "sumo-DRT/osm:", "sumo-fkk_in/ingolstadt", "gen-tee3",
                   "gen-star5", "gen-joined", "gen-programs"):
        assert any(n.startswith(prefix) for n in names), prefix
    joined = read_junction(next(c for c in cases if c.name == "gen-joined").net)
    assert len(joined.node_ids) == 2  # one junction of two SUMO nodes sharing one light
    star = read_junction(next(c for c in cases if c.name == "gen-star5").net)
    tee = read_junction(next(c for c in cases if c.name == "gen-tee3").net)
    assert (len(star.approaches), len(tee.approaches)) == (5, 3)
    south = tee.approach("s_in")
    assert not any("bicycle" in lane.allowed_classes for lane in south.entrance_lanes)
    assert tee.lead_in(south.entrance_lanes[0].id).edges == ("s2_in", "s_in")  # 25 m, then the road before


def test_every_task_has_drivable_candidates_or_one_clear_refusal(cases: list[Case]) -> None:
    """Candidates within the steering limit whose curves keep the footprint on the road and off
    other approaches' entrances; or a refusal, of one movement or of the whole task, in one line."""
    tasks = refused_tasks = refused_movements = 0
    for case in cases:
        junction = read_junction(case.net, case.junction_id)
        for row in check_paths(case, junction):
            tasks += 1
            assert (row.over_limit, row.off_road) == (0, 0), row
            assert row.max_curvature <= MAX_CURVATURE + 1e-6, row
            for line in [*row.refused, *([row.error] if row.error else [])]:
                assert line and "\n" not in line, row
            refused_tasks += row.error is not None
            refused_movements += len(row.refused)
            if row.error is None:
                assert row.candidates > 0, row
    assert tasks >= 400 and refused_tasks <= tasks // 20, (tasks, refused_tasks)


def test_a_refused_task_says_why_and_the_rest_drive(cases: list[Case]) -> None:
    """One known refusal: a right turn of the A10KW OSM cut whose kerb is drawn so tight that no
    curve a car can steer keeps to the road; the message names how tight the least bent one is."""
    case = next(c for c in cases if c.name.startswith("sumo-A10KW/osm:cluster_1643085231"))
    junction = read_junction(case.net, case.junction_id)
    with pytest.raises(PlanningError, match=r"^no drivable right-turn path: .* no curve a car can drive: "
                                            r"the least bent one that keeps to the road bends 0\.2\d\d 1/m"):
        plan_task(junction, "right", approach="222448597#0").require()
    for task in ("left", "straight"):
        plan = plan_task(junction, task, approach="222448597#0")
        road = road_check(junction, "222448597#0")
        for c in plan.require():
            curve = c.segment == "curve"
            assert not c.exceeds_limit and road.problem(c.points[curve], c.heading[curve]) is None


def test_every_walk_the_demand_may_draw_is_one_sumo_routes(cases: list[Case], tmp_path: Path) -> None:
    """Pedestrians walk only between sidewalks the junction's walking areas and crossings join
    (sim/traffic.py ``walkable_pairs``): every such walk of every junction with sidewalks and
    crossings, all departing at once, and SUMO departs each one (a walk it cannot route stops the
    run: "No connection found"). Ingolstadt's 335525545, whose two sidewalk groups no crossing
    joins, is among them."""
    checked = set()
    for case in cases:
        junction = read_junction(case.net, case.junction_id)
        if not (junction.crossings and junction.sidewalks):
            continue
        walks = {lane.edge_id for lane in junction.sidewalks}
        legs = [a.incoming_edge for a in junction.approaches if a.incoming_edge in walks]
        targets = [a.outgoing_edge for a in junction.approaches if a.outgoing_edge in walks]
        pairs = [(e, t) for e, reach in walkable_pairs(junction, legs, targets).items() for t in reach]
        assert pairs, case.name
        plan = DemandPlan(tuple(Departure(f"ped{k}", "pedestrian", 0.0, e, t, depart_pos_m=0.0, arrival_pos_m=0.0)
                                for k, (e, t) in enumerate(pairs)))
        routes = write_plan(plan, tmp_path / f"{len(checked)}.rou.xml")
        with SumoSession().start(case.net, [routes], seed=0) as sim:
            departed = 0
            for _ in range(2):
                sim.step()
                departed += len(sim.departed_last_step)
            assert departed == len(pairs), case.name
        checked.add(case.name)
    assert "sumo-fkk_in/ingolstadt:335525545" in checked and len(checked) >= 10, checked


@pytest.mark.parametrize("name", EPISODE_CASES)
def test_episodes_end_without_error_and_without_an_early_collision(cases: list[Case], name: str) -> None:
    case = next(c for c in cases if c.name == name or c.name.startswith(name + ":"))  # a net's first
    junction = read_junction(case.net, case.junction_id)
    ran = 0
    for task in ("left", "straight", "right"):
        if not junction.default_approach().connections_for(task):
            continue
        for policy, seeds in SEEDS.items():
            for row in run_case(case, task, policy, seeds, timeout_s=EPISODE_TIMEOUT_S):
                if row.outcome == "refused":  # the network refuses the task: one line, no episode
                    assert row.detail and "\n" not in row.detail
                    continue
                ran += 1
                assert row.outcome != "error", row
                assert not row.early_collision, f"collision at {row.time_s:.1f} s < {EARLY_COLLISION_S} s: {row}"
    assert ran > 0


def test_a_departure_due_in_the_last_warm_up_step_stays_out_of_the_start_zone(cases: list[Case]) -> None:
    """DRT's OSM cut: a car due 0.08 s before the ego's entry, on the ego's own edge, was inserted
    by the step the entry's clearing takes, 4.1 m ahead of the ego: a collision at 0.1 s. Such a
    departure is now left out of the episode's demand with the rest of the start zone's."""
    case = next(c for c in cases if c.name.startswith("sumo-DRT/osm:cluster_1560223815"))
    spec, problems = scenario_for(case, "left", 1, base_seed=20261206)
    assert not problems
    controller = RuleBasedController()
    with World(to_world_config(spec)) as world:  # the scenario's own timeout: it sizes the demand
        observation, outcome = world.reset(1809358627), None
        controller.reset(world.candidates)
        while outcome is None and world.time_s < EARLY_COLLISION_S:
            observation, outcome = world.step(controller.decide(observation).action)
    assert outcome is None, outcome
