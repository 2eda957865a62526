"""Which of the other participants make a trained policy drive into the vehicle ahead of it.

    .venv/bin/python benchmarks/research/clutter_probe.py scenarios/nominal/c_three_lane-left.yaml \
        --policy models/apg.pt [--runs 50] [--look-back 2]

``failure_modes.py`` found (docs/tried/training.md, "The stopping tail") that before a
collision with a standing vehicle in front, the policy's plan from the state as seen meets some
circle far more often than with every slot but the vehicle ahead padded. This probe takes the same
states (``--look-back`` seconds before each collision of the scenario's first ``--runs`` seeded
episodes) and asks, of every state with a vehicle ahead (within 2.5 m of the ego's axis), with the
training model (T = 25, ξ ≡ 0):

* does the plan meet **that** vehicle (its circles against the ego's along the plan), as seen, with
  the vehicle alone in the first slot, and with the vehicle alone in the slot it had as seen (the
  slots are sorted by distance, so among traffic the car ahead is rarely in the first one)?
* where the plan meets it as seen but not alone: which single participant, padded, makes the plan
  keep clear of it (leave one out), and which, alone beside it (the two in the slots the state
  builder would give them), makes the plan meet it (add one); each such participant by kind, place
  and motion in the ego's frame.

A slot effect (alone in its own slot the plan meets it, alone in the first it does not) says the
networks did not learn to read every slot alike; a culprit participant says which other traffic the
policy trades the vehicle ahead against.
"""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402

from crossroads.policy.ref import parse_policy  # noqa: E402
from crossroads.scenario.spec import load_scenario, run_seeds, to_world_config  # noqa: E402
from crossroads.idc.decision import IdcController  # noqa: E402
from crossroads.idc.state import KIND_OF_SLOT, O_PHI, O_PX, O_PY, O_V, pad_participant, path_tensors  # noqa: E402
from crossroads.rl.buffer import Samples, to_batch  # noqa: E402
from crossroads.rl.checkpoint import load_networks  # noqa: E402
from crossroads.rl.idc_model import IDCModel  # noqa: E402
from crossroads.sim.world import World  # noqa: E402
from probing import (  # noqa: E402
    CORRIDOR_HALF_WIDTH_M,
    HORIZON,
    STANDING_MPS,
    collision_lookbacks,
    ego_frame,
    model_parser,
    vehicle_ahead,
)


FIRST_SLOT_OF_KIND = {kind: KIND_OF_SLOT.index(kind) for kind in set(KIND_OF_SLOT)}  # where each block begins


@dataclass(frozen=True)
class Probe:
    """One state with a vehicle ahead: which slot holds it and whether the plan meets it."""

    slot: int  # the vehicle ahead's slot as seen
    meets_seen: bool
    meets_alone_first: bool  # the vehicle alone, in slot 0
    meets_alone_own: bool  # the vehicle alone, in its own slot
    meets_moved_first: bool  # as seen, but the vehicle moved to slot 0 (the vehicles before it one slot on)
    others: int  # participants besides the vehicle (in the states the tests below ran on, else 0)
    leave_one_out: tuple[int, ...]  # slots whose padding alone clears the plan of the vehicle
    add_one: tuple[int, ...]  # slots that, alone beside the vehicle, make the plan meet it


def real_slots(ego: np.ndarray, others: np.ndarray) -> list[int]:
    """Slots that hold a participant, not the padding behind the ego."""
    pad = pad_participant(ego)
    return [i for i in range(len(others)) if not np.allclose(others[i, :2], pad[:2], atol=1e-3)]


class PlanProbe:
    """The policy's closed-loop plan in the training model, and whether it meets one participant."""

    def __init__(self, model: IDCModel, controller: IdcController) -> None:
        self.model, self.controller = model, controller

    def plan(self, sample: Samples) -> list[torch.Tensor]:
        """The policy's T actions from each state of ``sample`` (its mean action at every step)."""
        actions: list[torch.Tensor] = []

        def act(s: torch.Tensor, _: int) -> torch.Tensor:
            actions.append(self.controller.policy.mean_action(s))
            return actions[-1]

        with torch.no_grad():
            self.model.rollout(to_batch(sample), act, None, HORIZON)
        return actions

    def meets(self, sample: Samples, slot: np.ndarray) -> np.ndarray:
        """Whether the policy's plan from each state of ``sample`` meets the circles of the
        participant in ``slot[b]``: the plan replayed against that participant alone (the ego's
        motion does not depend on the others, nor does one participant's prediction on another's)."""
        actions = self.plan(sample)
        alone = only_slot(sample, slot, keep_slot=True)
        with torch.no_grad():
            out = self.model.rollout(to_batch(alone), lambda _s, i: actions[i], None, HORIZON)
        return (out.overlap_m > 0).numpy()


def only_slot(sample: Samples, slot: np.ndarray, keep_slot: bool) -> Samples:
    """``sample`` with every slot padded but ``slot[b]``; the kept participant stays in its slot
    (``keep_slot``) or moves to slot 0."""
    others = np.empty_like(sample.others)
    kappa = np.zeros_like(sample.kappa)
    for b, ego in enumerate(sample.ego.astype(np.float64)):
        others[b] = pad_participant(ego)
        to = slot[b] if keep_slot else 0
        others[b, to], kappa[b, to] = sample.others[b, slot[b]], sample.kappa[b, slot[b]]
    return Samples(sample.ego, others, kappa, sample.path, sample.stop)


def moved_first(sample: Samples, slot: np.ndarray) -> Samples:
    """``sample`` with the vehicle in ``slot[b]`` moved to slot 0 and the vehicles before it one slot on."""
    others, kappa = sample.others.copy(), sample.kappa.copy()
    for b, k in enumerate(slot):
        order = [k] + [i for i in range(k + 1) if i != k]
        others[b, : k + 1], kappa[b, : k + 1] = sample.others[b, order], sample.kappa[b, order]
    return Samples(sample.ego, others, kappa, sample.path, sample.stop)


def pair_as_built(sample: Samples, row: int, car: int, other: int) -> tuple[Samples, np.ndarray]:
    """Row ``row`` of ``sample`` (one row) with only the vehicle in slot ``car`` and the participant in
    slot ``other`` left, in the slots the state builder would give the two (each kind from the first
    slot of its block, the vehicles by distance); and the vehicle's new slot (shape (1,))."""
    ego = sample.ego[row].astype(np.float64)
    others = np.tile(pad_participant(ego), (len(KIND_OF_SLOT), 1)).astype(sample.others.dtype)
    kappa = np.zeros_like(sample.kappa[row:row + 1])
    if KIND_OF_SLOT[other] == "vehicle":
        distance = lambda k: float(np.hypot(*(sample.others[row, k, :2] - ego[:2])))  # noqa: E731
        placed = dict(zip(sorted((car, other), key=distance), (0, 1), strict=True))
    else:
        placed = {car: 0, other: FIRST_SLOT_OF_KIND[KIND_OF_SLOT[other]]}
    for source, to in placed.items():
        others[to], kappa[0, to] = sample.others[row, source], sample.kappa[row, source]
    one = sample.take(slice(row, row + 1))
    return Samples(one.ego, others[None], kappa, one.path, one.stop), np.array([placed[car]])


def with_slot_padded(sample: Samples, row: int, slot: int) -> Samples:
    """Row ``row`` of ``sample`` (one row) with ``slot`` padded."""
    one = sample.take(slice(row, row + 1))
    others, kappa = one.others.copy(), one.kappa.copy()
    others[0, slot], kappa[0, slot] = pad_participant(sample.ego[row].astype(np.float64)), 0.0
    return Samples(one.ego, others, kappa, one.path, one.stop)


def describe(ego: np.ndarray, other: np.ndarray, kind: str) -> str:
    """A participant's kind, place and motion in the ego's frame, coarsely (for counting)."""
    along, across = ego_frame(ego, float(other[O_PX]), float(other[O_PY]))
    place = "ahead" if along > 2.0 else ("behind" if along < -2.0 else "beside")
    side = "in the ego's lane" if abs(across) < CORRIDOR_HALF_WIDTH_M else ("left" if across > 0 else "right")
    if float(other[O_V]) < STANDING_MPS:
        motion = "standing"
    else:
        rel = float(np.cos(float(other[O_PHI]) - float(ego[4])))
        motion = "same way" if rel > 0.7 else ("oncoming" if rel < -0.7 else "crossing")
    return f"{kind} {place} {side}, {motion}"


def probe_states(probe: PlanProbe, seen: Samples) -> tuple[list[Probe], Counter[str], Counter[str]]:
    """Every state of ``seen`` with a vehicle ahead, probed (module docstring); and the culprits of
    the leave-one-out and add-one tests, described."""
    rows = [(b, vehicle_ahead(seen.ego[b].astype(np.float64), seen.others[b].astype(np.float64)))
            for b in range(len(seen.ego))]
    rows = [(b, k) for b, k in rows if k is not None]
    if not rows:
        return [], Counter(), Counter()
    index = np.array([b for b, _ in rows])
    sub = seen.take(index)
    slot = np.array([k for _, k in rows])
    first = np.zeros_like(slot)
    meets_seen = probe.meets(sub, slot)
    meets_first = probe.meets(only_slot(sub, slot, keep_slot=False), first)
    meets_own = probe.meets(only_slot(sub, slot, keep_slot=True), slot)
    meets_moved = probe.meets(moved_first(sub, slot), first)
    probes: list[Probe] = []
    dropped: Counter[str] = Counter()
    added: Counter[str] = Counter()
    for b in range(len(slot)):
        ego = sub.ego[b].astype(np.float64)
        out: tuple[int, ...] = ()
        add: tuple[int, ...] = ()
        rest: list[int] = []
        if meets_seen[b] and not meets_first[b]:
            rest = [j for j in real_slots(ego, sub.others[b]) if j != slot[b]]
            one = sub.take(slice(b, b + 1))
            out = tuple(j for j in rest if not probe.meets(with_slot_padded(one, 0, j), np.array([slot[b]]))[0])
            add = tuple(j for j in rest if probe.meets(*pair_as_built(one, 0, int(slot[b]), j))[0])
            dropped.update(describe(ego, sub.others[b, j], KIND_OF_SLOT[j]) for j in out)
            added.update(describe(ego, sub.others[b, j], KIND_OF_SLOT[j]) for j in add)
        probes.append(Probe(int(slot[b]), bool(meets_seen[b]), bool(meets_first[b]), bool(meets_own[b]),
                            bool(meets_moved[b]), len(rest), out, add))
    return probes, dropped, added


def main() -> None:
    parser = model_parser(__doc__.splitlines()[0], runs=50)
    parser.add_argument("--look-back", type=float, default=2.0, help="[s] before impact (≤ 5)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    spec = load_scenario(args.scenario)
    ref = parse_policy(args.policy)  # models/apg.pt+shield: with the safety shield
    if ref.kind != "checkpoint":
        parser.error(f"--policy: a trained checkpoint (.pt), optionally +shield; got {args.policy!r}")
    checkpoint, shield = ref.target, ref.shield
    networks, _ = load_networks(Path(checkpoint))
    controller = IdcController(networks.policy, networks.value, name=Path(checkpoint).stem, shield=shield)
    with World(to_world_config(spec, args.scenario.parent)) as world:
        model = IDCModel(path_tensors(world.candidates, dtype=torch.float32), preview=controller.preview)
        seen = [c.before for c in collision_lookbacks(world, controller, run_seeds(spec, args.runs), args.look_back)]
    print(f"policy {args.policy} on {args.scenario} ({args.runs} seeded runs): {len(seen)} collisions")
    if not seen:
        return
    probes, dropped, added = probe_states(PlanProbe(model, controller), Samples.concat(seen))
    n = len(probes)
    print(f"{args.look_back:g} s before impact, {n} states with a vehicle ahead (|across| < {CORRIDOR_HALF_WIDTH_M:g} m); "
          f"the policy's plan (T = {HORIZON}, ξ ≡ 0) meets that vehicle:")
    print(f"  as seen                         {sum(p.meets_seen for p in probes):>4} of {n}")
    print(f"  alone, in the first slot        {sum(p.meets_alone_first for p in probes):>4} of {n}")
    print(f"  alone, in its own slot          {sum(p.meets_alone_own for p in probes):>4} of {n}")
    print(f"  as seen, moved to the first slot{sum(p.meets_moved_first for p in probes):>4} of {n}")
    slots = Counter(p.slot for p in probes)
    print("  its slot as seen: " + ", ".join(f"{s}: {slots[s]}" for s in sorted(slots)))
    gap = [p for p in probes if p.meets_seen and not p.meets_alone_first]
    print(f"{len(gap)} states meet it as seen but not alone in the first slot; of those:")
    print(f"  alone in its own slot it meets it in {sum(p.meets_alone_own for p in gap)}")
    others = sum(p.others for p in gap)
    print(f"  padding one participant clears the plan in {sum(bool(p.leave_one_out) for p in gap)} "
          f"({sum(len(p.leave_one_out) for p in gap)} of the {others} participants around)")
    print(f"  one participant beside it makes the plan meet it in {sum(bool(p.add_one) for p in gap)} "
          f"({sum(len(p.add_one) for p in gap)} of the {others} participants around, each alone with it)")
    for title, counts in (("padded, clears the plan", dropped), ("alone beside it, makes the plan meet it", added)):
        if counts:
            print(f"participants that, {title}:")
            for what, k in counts.most_common():
                print(f"  {what:<44}{k:>4}")


if __name__ == "__main__":
    main()
