"""Any SUMO intersection, for real: candidate paths and episodes on every real junction at hand.

    .venv/bin/python benchmarks/real_nets.py                       # paths, then 20 seeds per task
    .venv/bin/python benchmarks/real_nets.py --seeds 3 --only cross cologne1
    .venv/bin/python benchmarks/real_nets.py --paths-only
    .venv/bin/python benchmarks/real_nets.py --base-seed 20261206 --shard 1/2   # and 2/2 beside it

The corpus (:func:`corpus`): every traffic-light junction with at least three car approaches of
``../shared/realnets`` (a RESCO Cologne junction, the sumo-rl single intersection), of the example
nets shipped inside the eclipse-sumo wheel (``sumo/tools/**.net.xml[.gz]``: OSM cuts of several
cities, the RiLSA examples, the game nets), and of four nets built here with netconvert for what
those lack (:func:`generated_nets`): a T junction with a bike-less approach and a short approach
edge, a five-leg junction with crossings, a divided road whose two nodes share one joined traffic
light, and a light with two programs where SUMO runs the second.

For every junction, every approach and every task it has, ``paths`` either gives candidates whose
curves stay within the ego's steering limit (0.16 1/m) and on the road (``planning.drivable``), or
refuses with one line; every candidate over the limit is counted. Then, from the default approach
(the south), ``--seeds`` seeded episodes per task with the rule controller and with SUMO's own
driver (policy ``sumo``), each with the scenario defaults settled as a user would settle them from
what ``network_problems`` (the check of run, evaluate and the API) answers: the longest start the
road allows where 40 m does not fit, the first program that shows the ego green where the one
SUMO runs never does; a task the network still refuses is reported as refused, in one line.
Counted: ``error`` outcomes (an exception anywhere in the episode) and collisions before t = 2 s
(``EARLY_COLLISION_S``).

Exit status 1 when a target is missed: a candidate over the limit or off the road, an error, or
an early collision. ``tests/sim/test_real_nets.py`` runs the same checks on a few seeds.
"""

from __future__ import annotations

import argparse
import glob
import math
import os
import subprocess
import sys
import tempfile
import time
import traceback
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

from crossroads.evaluation.episode import run_episode  # noqa: E402
from crossroads.evaluation.sumo_driver import SumoDriverPolicy  # noqa: E402
from crossroads.idc.rule_based import RuleBasedController  # noqa: E402
from crossroads.intersections.build import find_netconvert  # noqa: E402
from crossroads.network.junction import JunctionError, read_junction  # noqa: E402
from crossroads.network.road import TASKS, Junction  # noqa: E402
from crossroads.network.netxml import TRAFFIC_LIGHT_TYPES, read_net_xml  # noqa: E402
from crossroads.planning import PlanningError, plan_task  # noqa: E402
from crossroads.planning.curves import MAX_CURVATURE  # noqa: E402
from crossroads.planning.drivable import road_check  # noqa: E402
from crossroads.scenario.network_checks import network_problems  # noqa: E402
from crossroads.scenario.spec import (  # noqa: E402
    ScenarioSpec,
    run_seeds,
    to_world_config,
    validate_scenario,
)
from crossroads.sim.world import World  # noqa: E402

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("CROSSROADS_SHARED_DIR", REPO_ROOT.parent / "shared"))
EARLY_COLLISION_S = 2.0  # [s] a collision before this no driver could avoid (issue 36)
POLICIES = ("rule", "sumo")


# --- the junctions ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """One traffic-light junction of the corpus."""

    name: str  # "<net>" or "<net>:<junction id>"
    net: Path
    junction_id: str | None  # None: the net's default junction


def _sumo_examples() -> list[Path]:
    import sumo

    root = Path(sumo.SUMO_HOME) / "tools"
    return sorted(Path(p) for p in glob.glob(str(root / "**" / "*.net.xml*"), recursive=True))


def junctions_of(net: Path) -> list[str]:
    """Ids of the traffic-light junctions of ``net`` that read as an intersection (≥ 3 car
    approaches); nodes of one joined junction count once (its first id)."""
    ids: list[str] = []
    seen: set[frozenset[str]] = set()
    nodes = read_net_xml(net).nodes
    for node_id in sorted(n for n, rec in nodes.items() if rec.type in TRAFFIC_LIGHT_TYPES):
        try:
            junction = read_junction(net, node_id)
        except JunctionError:
            continue  # a pedestrian light, a ramp meter, a node with fewer than 3 car approaches
        members = frozenset(junction.node_ids)
        if members not in seen:
            seen.add(members)
            ids.append(node_id)
    return ids


def corpus(generated_dir: Path) -> list[Case]:
    """Every junction of the corpus (module docstring); nets built into ``generated_dir``."""
    nets: list[tuple[str, Path]] = [
        ("cologne1", SHARED / "realnets" / "resco_cologne1" / "cologne1.net.xml"),
        ("sumo-rl", SHARED / "realnets" / "sumo-rl_2way-single-intersection" / "single-intersection.net.xml"),
    ]
    for path in _sumo_examples():
        nets.append((f"sumo-{path.parent.name}/{path.name.split('.')[0]}", path))
    nets += [(f"gen-{name}", path) for name, path in generated_nets(generated_dir).items()]
    cases: list[Case] = []
    seen_files: set[bytes] = set()
    for name, path in nets:
        content = path.read_bytes()
        if content in seen_files:  # the RiLSA examples ship one net under two names
            continue
        seen_files.add(content)
        ids = junctions_of(path)
        cases += [Case(name if len(ids) == 1 else f"{name}:{jid}", path, jid) for jid in ids]
    return cases


# --- nets built here -------------------------------------------------------------------------------


def _xml(path: Path, root: str, rows: list[str]) -> Path:
    path.write_text(f"<{root}>\n" + "\n".join(f"  {r}" for r in rows) + f"\n</{root}>\n")
    return path


def _netconvert(out: Path, *args: str) -> Path:
    subprocess.run([str(find_netconvert()), *args, "-o", str(out), "--no-turnarounds", "true"],
                   check=True, capture_output=True, text=True)
    return out


def _leg_edges(centre: str, legs: list[tuple[str, float, float]], lanes: int,
               extra: str = "") -> list[str]:
    """Two-way edges between ``centre`` and each leg node, ``lanes`` lanes each way."""
    rows = []
    for name, _, _ in legs:
        rows.append(f'<edge id="{name}_in" from="{name}" to="{centre}" numLanes="{lanes}" speed="13.89" {extra}/>')
        rows.append(f'<edge id="{name}_out" from="{centre}" to="{name}" numLanes="{lanes}" speed="13.89" {extra}/>')
    return rows


def generated_nets(out_dir: Path) -> dict[str, Path]:
    """Four nets for what the shipped ones lack (module docstring), built into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    nets: dict[str, Path] = {}

    # a T junction: the south approach forbids bicycles and its last edge is 25 m long (a node
    # where nothing changes before it), no sidewalks anywhere
    nodes = ['<node id="C" x="0" y="0" type="traffic_light"/>', '<node id="w" x="-150" y="0"/>',
             '<node id="e" x="150" y="0"/>', '<node id="s" x="0" y="-25"/>',
             '<node id="s2" x="0" y="-160"/>']
    edges = _leg_edges("C", [("w", 0, 0), ("e", 0, 0)], 2)
    edges += ['<edge id="s_in" from="s" to="C" numLanes="2" speed="13.89" disallow="bicycle pedestrian"/>',
              '<edge id="s_out" from="C" to="s" numLanes="2" speed="13.89" disallow="bicycle pedestrian"/>',
              '<edge id="s2_in" from="s2" to="s" numLanes="2" speed="13.89" disallow="bicycle pedestrian"/>',
              '<edge id="s2_out" from="s" to="s2" numLanes="2" speed="13.89" disallow="bicycle pedestrian"/>']
    nets["tee3"] = _netconvert(out_dir / "tee3.net.xml",
                               "-n", str(_xml(out_dir / "tee3.nod.xml", "nodes", nodes)),
                               "-e", str(_xml(out_dir / "tee3.edg.xml", "edges", edges)))

    # five legs, one lane each way, sidewalks and crossings guessed by netconvert
    legs = [(f"l{k}", 150 * math.sin(math.radians(72 * k)), 150 * math.cos(math.radians(72 * k + 180)))
            for k in range(5)]
    nodes = ['<node id="C" x="0" y="0" type="traffic_light"/>'] + [
        f'<node id="{n}" x="{x:.2f}" y="{y:.2f}"/>' for n, x, y in legs]
    nets["star5"] = _netconvert(out_dir / "star5.net.xml",
                                "-n", str(_xml(out_dir / "star5.nod.xml", "nodes", nodes)),
                                "-e", str(_xml(out_dir / "star5.edg.xml", "edges", _leg_edges("C", legs, 1))),
                                "--sidewalks.guess", "true", "--crossings.guess", "true")

    # a divided east-west road (carriageways 14 m apart) crossed by a two-way side road: two nodes
    # 14 m apart on the side road, one joined traffic light (tls.join), not one merged node
    nodes = ['<node id="n" x="0" y="7" type="traffic_light"/>', '<node id="s" x="0" y="-7" type="traffic_light"/>',
             '<node id="wn" x="-150" y="7"/>', '<node id="en" x="150" y="7"/>',
             '<node id="ws" x="-150" y="-7"/>', '<node id="es" x="150" y="-7"/>',
             '<node id="N" x="0" y="150"/>', '<node id="S" x="0" y="-150"/>']
    edges = ['<edge id="wb_in" from="en" to="n" numLanes="2" speed="13.89"/>',
             '<edge id="wb_out" from="n" to="wn" numLanes="2" speed="13.89"/>',
             '<edge id="eb_in" from="ws" to="s" numLanes="2" speed="13.89"/>',
             '<edge id="eb_out" from="s" to="es" numLanes="2" speed="13.89"/>',
             '<edge id="N_in" from="N" to="n" numLanes="1" speed="13.89"/>',
             '<edge id="N_out" from="n" to="N" numLanes="1" speed="13.89"/>',
             '<edge id="S_in" from="S" to="s" numLanes="1" speed="13.89"/>',
             '<edge id="S_out" from="s" to="S" numLanes="1" speed="13.89"/>',
             '<edge id="mid_sn" from="s" to="n" numLanes="1" speed="13.89"/>',
             '<edge id="mid_ns" from="n" to="s" numLanes="1" speed="13.89"/>']
    nets["joined"] = _netconvert(out_dir / "joined.net.xml",
                                 "-n", str(_xml(out_dir / "joined.nod.xml", "nodes", nodes)),
                                 "-e", str(_xml(out_dir / "joined.edg.xml", "edges", edges)),
                                 "--tls.join", "true", "--tls.join-dist", "20", "--junctions.join", "false")

    # a regular crossroads whose light has a second program, "utopia" (6 phases, a 62 s cycle),
    # loaded last: SUMO runs it, not netconvert's 4-phase "0"
    legs4 = [("w", -150, 0), ("e", 150, 0), ("s", 0, -150), ("n", 0, 150)]
    nodes = ['<node id="C" x="0" y="0" type="traffic_light"/>'] + [
        f'<node id="{n}" x="{x}" y="{y}"/>' for n, x, y in legs4]
    first = _netconvert(out_dir / "programs0.net.xml",
                        "-n", str(_xml(out_dir / "programs.nod.xml", "nodes", nodes)),
                        "-e", str(_xml(out_dir / "programs.edg.xml", "edges", _leg_edges("C", legs4, 2))))
    from crossroads.sim.signals import read_program

    base = read_program(first, "C")
    ns_green, ew_green = base.phases[0].state, base.phases[2].state
    phases = [(20, ns_green), (3, base.phases[1].state), (2, "r" * base.n_links),
              (29, ew_green), (3, base.phases[3].state), (5, "r" * base.n_links)]
    rows = "".join(f'<phase duration="{d}" state="{s}"/>' for d, s in phases)
    tll = out_dir / "utopia.tll.xml"
    tll.write_text(f'<tlLogics><tlLogic id="C" type="static" programID="utopia" offset="0">{rows}'
                   "</tlLogic></tlLogics>")
    nets["programs"] = _netconvert(out_dir / "programs.net.xml", "-s", str(first), "--tllogic-files", str(tll))
    return nets


# --- paths -------------------------------------------------------------------------------------------


@dataclass
class PathRow:
    """One approach × task of one junction."""

    case: str
    approach: str
    task: str
    candidates: int = 0
    max_curvature: float = 0.0  # [1/m] over the task's candidates
    over_limit: int = 0  # candidates bending tighter than the ego can steer
    off_road: int = 0  # candidates whose curve fails the road check (must be 0: they are refused)
    refused: list[str] = field(default_factory=list)  # one line per refused movement
    error: str | None = None  # the one line of a task refused outright


def check_paths(case: Case, junction: Junction) -> Iterator[PathRow]:
    """Every approach × task of ``junction``: its candidates, re-checked against the road."""
    for approach in junction.approaches:
        road = road_check(junction, approach.id)
        for task in TASKS:
            if not approach.connections_for(task):
                continue
            row = PathRow(case.name, approach.id, task)
            try:
                plan = plan_task(junction, task, approach=approach)
                plan.require()
            except PlanningError as exc:
                row.error = str(exc)
                yield row
                continue
            row.refused = [r.reason for r in plan.refused]
            for c in plan.candidates:
                row.candidates += 1
                row.max_curvature = max(row.max_curvature, c.max_curvature)
                row.over_limit += c.exceeds_limit
                curve = c.segment == "curve"
                row.off_road += road.problem(c.points[curve], c.heading[curve]) is not None
            yield row


# --- episodes ------------------------------------------------------------------------------------------


@dataclass
class EpisodeRow:
    case: str
    task: str
    policy: str
    seed: int
    outcome: str  # the world's outcome, or "error"
    time_s: float
    detail: str = ""

    @property
    def early_collision(self) -> bool:
        return self.outcome == "collision" and self.time_s < EARLY_COLLISION_S


def scenario_for(case: Case, task: str, seeds: int,
                 base_seed: int = 0) -> tuple[ScenarioSpec, list[tuple[str, str]]]:
    """The scenario of one junction and task as a user would settle it, and what the network
    still refuses of it (``network_problems``, the check of run, evaluate and the API): the
    defaults, then, where the network says so, the ego as far out as the road allows (the
    refusal names how far) and the first program that shows the ego green (it names those)."""
    intersection = {"net": str(case.net)} | ({"junction": case.junction_id} if case.junction_id else {})
    fields: dict[str, object] = {"version": 1, "name": "corpus", "intersection": intersection,
                                 "task": task, "runs": seeds, "seed": base_seed}
    spec = validate_scenario(fields, check_references=False)
    problems = network_problems(spec)
    for field_name, message in problems:
        if field_name == "ego.start_distance_m":
            room = float(message.rsplit("at most ", 1)[1].split(" m")[0])
            fields["ego"] = {"start_distance_m": max(room, 0.1)}
        elif field_name == "lights.ego" and "(lights.program)" in message:
            fields["lights"] = {"program": message.rsplit("program(s) '", 1)[1].split("'", 1)[0]}
    if "ego" in fields or "lights" in fields:
        spec = validate_scenario(fields, check_references=False)
        problems = network_problems(spec)
    return spec, problems


def run_case(case: Case, task: str, policy: str, seeds: int,
             timeout_s: float | None = None, base_seed: int = 0) -> Iterator[EpisodeRow]:
    """``seeds`` episodes of one junction, task and policy (``rule`` | ``sumo``); a scenario the
    network refuses gives one row of outcome ``refused`` (its reasons as the detail)."""
    spec, problems = scenario_for(case, task, seeds, base_seed)
    if problems:
        yield EpisodeRow(case.name, task, policy, -1, "refused", 0.0,
                         "; ".join(f"{f}: {m}" for f, m in problems))
        return
    config = to_world_config(spec)
    if timeout_s is not None:
        config = replace(config, timeout_s=timeout_s)
    try:
        world = World(config)
    except Exception as exc:  # noqa: BLE001 - the world itself fails: every episode is an error
        for seed in run_seeds(spec):
            yield EpisodeRow(case.name, task, policy, seed, "error", 0.0, f"{type(exc).__name__}: {exc}")
        return
    with world:
        for seed in run_seeds(spec):
            controller = RuleBasedController() if policy == "rule" else SumoDriverPolicy()
            try:
                result = run_episode(world, controller, seed)
            except Exception as exc:  # noqa: BLE001 - what a batch records as outcome "error"
                last = traceback.format_exception_only(type(exc), exc)[-1].strip()
                yield EpisodeRow(case.name, task, policy, seed, "error", getattr(world, "time_s", 0.0), last)
                continue
            yield EpisodeRow(case.name, task, policy, seed, result.outcome, result.time_s, result.detail)


# --- the report -------------------------------------------------------------------------------------


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="episodes per junction, task and policy")
    parser.add_argument("--policies", nargs="*", default=list(POLICIES), choices=POLICIES)
    parser.add_argument("--only", nargs="*", default=None, help="junction names (prefixes) to run")
    parser.add_argument("--paths-only", action="store_true", help="check the candidate paths only")
    parser.add_argument("--timeout", type=float, default=None, help="[s] episode timeout (default: the scenario's)")
    parser.add_argument("--base-seed", type=int, default=0,
                        help="the scenarios' base seed (run_seeds derives each episode's seed from it)")
    parser.add_argument("--shard", default="1/1", metavar="K/N",
                        help="run only the K-th of N interleaved slices of the corpus (for N processes)")
    args = parser.parse_args()
    shard, shards = (int(x) for x in args.shard.split("/"))
    if not 1 <= shard <= shards:
        parser.error(f"--shard: K must be in 1..N, got {args.shard}")
    failed = False
    with tempfile.TemporaryDirectory(prefix="crossroads-corpus-") as tmp:
        cases = corpus(Path(tmp))
        if args.only:
            cases = [c for c in cases if any(c.name.startswith(p) for p in args.only)]
        cases = cases[shard - 1::shards]
        print(f"{len(cases)} junctions; ego's steering limit {MAX_CURVATURE:.3f} 1/m")
        print(f"{'junction':34s} {'approach':22s} {'task':8s} {'cands':>5s} {'max κ':>6s}  refused / note")
        junctions: dict[str, Junction] = {}
        for case in cases:
            junctions[case.name] = junction = read_junction(case.net, case.junction_id)
            for row in check_paths(case, junction):
                bad = row.over_limit or row.off_road
                failed |= bool(bad)
                note = row.error or "; ".join(row.refused)
                print(f"{row.case[:34]:34s} {row.approach[:22]:22s} {row.task:8s} {row.candidates:5d} "
                      f"{row.max_curvature:6.3f}{'!' if bad else ' '} {note[:160]}")
        if args.paths_only:
            return int(failed)
        print(f"\n{'junction':34s} {'task':8s} {'policy':6s} outcomes (of {args.seeds} seeds)")
        totals = {"episodes": 0, "error": 0, "early": 0, "refused": 0}
        t0 = time.time()
        for case in cases:
            junction = junctions[case.name]
            for task in TASKS:
                if not junction.default_approach().connections_for(task):
                    continue
                for policy in args.policies:
                    rows = list(run_case(case, task, policy, args.seeds, args.timeout, args.base_seed))
                    counts: dict[str, int] = {}
                    for r in rows:
                        counts[r.outcome] = counts.get(r.outcome, 0) + 1
                    if rows[0].outcome == "refused":
                        print(f"{case.name[:34]:34s} {task:8s} {policy:6s} refused: {rows[0].detail[:150]}")
                        totals["refused"] += 1
                        continue
                    errors = [r for r in rows if r.outcome == "error"]
                    early = [r for r in rows if r.early_collision]
                    totals["episodes"] += len(rows)
                    totals["error"] += len(errors)
                    totals["early"] += len(early)
                    failed |= bool(errors or early)
                    mark = "!" if errors or early else " "
                    text = ", ".join(f"{k} {v}" for k, v in sorted(counts.items()))
                    first = (errors or early)[:1]
                    why = f"  [{first[0].seed}: {first[0].outcome} at {first[0].time_s:.1f} s {first[0].detail[:100]}]" if first else ""
                    print(f"{case.name[:34]:34s} {task:8s} {policy:6s}{mark}{text}{why}", flush=True)
        print(f"\n{totals['episodes']} episodes in {time.time() - t0:.0f} s: {totals['error']} error outcomes, "
              f"{totals['early']} collisions before {EARLY_COLLISION_S:g} s; {totals['refused']} "
              "junction x task x policy refused before any episode (one line each, above)")
    return int(failed)


if __name__ == "__main__":
    sys.exit(main())
