"""Which seeded runs no driver can pass: the ego's own lane held by a vehicle that never moves.

    .venv/bin/python benchmarks/blocked_lane.py scenarios/nominal/c_three_lane-left.yaml \
        --policy models/apg.pt+shield --policy rule --policy stand [--runs 200]

Every candidate path of the ego starts in its entrance lane, so a vehicle standing ahead of it
across all of them (in that lane, or at the start of the junction where the paths have not yet
parted) for a whole episode bars every path: no driver passes that run, however it drives. This
drives the scenario's first N seeded episodes (the seeds of ``crossroads evaluate``) with each
driver and, for every run that times out, finds the nearest vehicle ahead of the ego (along its
paths) whose body overlaps every candidate path (:func:`bars_every_path`) and when that vehicle
last moved (at ``STOPPED_SPEED_MPS`` or faster: the world's own threshold for a stopped vehicle).
A run is *held from the start* when that vehicle has not moved since ``HELD_FROM_S``: it stood
across every path the whole time the ego could have used to get past it.

``stand`` is a driver that brakes to a stand at once and stays there: behind it the lane's queue is
whatever the world makes of it without the ego near. A run held from the start under drivers as
different as a trained policy, the rule controller and ``stand`` is held by the world, not by how
the ego drove: the ego cannot hurry the vehicle ahead of it in its lane.

Prints, per driver, the outcomes and the held runs, then the runs held under every driver: at most
N minus that many runs can be passed by anyone, which bounds every driver's pass rate.
"""

from __future__ import annotations

import argparse
import os
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from crossroads.constants import JERK_MAX  # noqa: E402
from crossroads.evaluation.policies import load_controller  # noqa: E402
from crossroads.policy.ref import parse_policy  # noqa: E402
from crossroads.scenario.spec import load_scenario, run_seeds, to_world_config  # noqa: E402
from crossroads.idc.controller import Controller, Decision  # noqa: E402
from crossroads.planning import CandidatePath  # noqa: E402
from crossroads.sim.blocking import HELD_FROM_S, bars_every_path, nearest_barrier  # noqa: E402,F401 (re-exported)
from crossroads.sim.world import STOPPED_SPEED_MPS, World  # noqa: E402
from crossroads.sim.observation import Observation  # noqa: E402



class StandingDriver:
    """Brakes to a stand at once and stays there (full braking, the wheel held)."""

    name = "stand"

    def reset(self, candidates: Sequence[CandidatePath]) -> None:
        pass

    def decide(self, observation: Observation) -> Decision:
        return Decision(np.array([0.0, -JERK_MAX]), 0, "stop")


@dataclass(frozen=True)
class RunEnd:
    """How one seeded run ended, and what held the ego's lane."""

    seed: int
    outcome: str
    blocker: str | None  # the nearest vehicle ahead at the end that bars every candidate path
    blocker_last_moved_s: float | None  # [s] when it last moved (−inf: never, in the episode)
    blocker_ahead_m: float | None  # [m] from the ego's centre to the blocker's, along the paths

    @property
    def held_from_start(self) -> bool:
        return self.blocker_last_moved_s is not None and self.blocker_last_moved_s <= HELD_FROM_S


def drive(world: World, driver: Controller, seed: int) -> RunEnd:
    """One seeded episode with ``driver``, watching when every participant last moved."""
    obs = world.reset(seed)
    driver.reset(world.candidates)
    last_moved: dict[str, float] = {}
    outcome = None
    while outcome is None:
        obs, outcome = world.step(driver.decide(obs).action)
        snap = world.truth.participants
        for pid in snap.ids[snap.speed >= STOPPED_SPEED_MPS].tolist():
            last_moved[pid] = obs.time_s
    if outcome.kind != "timeout":
        return RunEnd(seed, outcome.kind, None, None, None)
    snap = world.truth.participants
    vehicles = [(k, float(snap.x[k]), float(snap.y[k]), float(snap.width[k]))
                for k in range(len(snap)) if snap.kind[k] == "vehicle"]
    found = nearest_barrier((float(obs.ego[0]), float(obs.ego[1])), vehicles, world.candidates)
    if found is None:
        return RunEnd(seed, outcome.kind, None, None, None)
    row, gap = found
    pid = str(snap.ids[row])
    return RunEnd(seed, outcome.kind, pid, last_moved.get(pid, -np.inf), gap)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", type=Path)
    parser.add_argument("--policy", action="append", required=True,
                        help="a driver: 'rule', 'stand' or a checkpoint (+shield); repeat for several")
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--seed", type=int, action="append", default=[],
                        help="only these of the runs' seeds (repeat); default: all of them")
    args = parser.parse_args()
    spec = load_scenario(args.scenario)
    seeds = run_seeds(spec, args.runs)
    if args.seed:
        unknown = sorted(set(args.seed) - set(seeds))
        if unknown:
            parser.error(f"--seed {unknown[0]} is not one of the first {args.runs} runs' seeds")
        seeds = [s for s in seeds if s in set(args.seed)]
    held_by: dict[str, set[int]] = {}
    with World(to_world_config(spec, args.scenario.parent)) as world:
        for ref in args.policy:
            driver = StandingDriver() if ref == "stand" else load_controller(parse_policy(ref))
            ends = [drive(world, driver, seed) for seed in seeds]
            outcomes = Counter(e.outcome for e in ends)
            held = [e for e in ends if e.held_from_start]
            held_by[ref] = {e.seed for e in held}
            never = sum(e.blocker_last_moved_s == -np.inf for e in held)
            print(f"{ref}: " + ", ".join(f"{k} {v}" for k, v in outcomes.most_common()))
            print(f"  timed out behind a vehicle across every candidate path that "
                  f"has not moved since t <= {HELD_FROM_S:g} s: {len(held)} ({never} never moved)")
            for e in held:
                moved = "never moved" if e.blocker_last_moved_s == -np.inf else f"last moved at {e.blocker_last_moved_s:.1f} s"
                print(f"    seed {e.seed:>10}: {e.blocker} {e.blocker_ahead_m:.1f} m ahead, {moved}")
    always = set.intersection(*held_by.values())
    print(f"held from the start under every driver ({', '.join(args.policy)}): {len(always)} of {len(seeds)} "
          f"runs; no driver passes more than {len(seeds) - len(always)} "
          f"({100.0 * (len(seeds) - len(always)) / len(seeds):.1f} %)")
    print("  seeds: " + " ".join(str(s) for s in sorted(always)))


if __name__ == "__main__":
    main()
