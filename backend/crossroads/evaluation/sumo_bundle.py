"""``crossroads export``: a scenario's episode as a plain SUMO bundle, for SUMO's own tools.

    crossroads export scenarios/nominal/c_three_lane-left.yaml --seed 1705482282 -o out/
    sumo-gui -c out/c_three_lane-left.sumocfg

What the world (:class:`crossroads.sim.world.World`) gives SUMO for episode ``seed``, as files:

* ``<name>.net.xml``: the network (the catalogue's build, or the scenario's net file);
* ``<name>.rou.xml``: the traffic demand drawn from the episode's seed, as the world draws it (same
  seed derivation, same duration), with the scenario's injected over-speeders (each a trip with
  its own speed factor);
* ``<name>.add.xml``: what the world sets through TraCI, as SUMO additionals: the §8 speed limits of
  the junction's lanes (variable speed signs from t = 0, :class:`~crossroads.sim.abnormal.AbnormalTraffic`),
  and the signal program unrolled over the episode so that the light jumps to the scenario's phase
  and offset at the end of the warm-up (``sim.signals.apply_start``), cycling on from there;
* ``<name>.ego.rou.xml``: the ego, entering at the end of the warm-up where the scenario starts it, on
  its task's route, driven by SUMO's own model (no controller runs in SUMO);
* ``<name>.sumocfg``: the options the world starts SUMO with (seed, step length, pedestrian model,
  collision handling, ...), ending with the episode's timeout.

Not in the bundle, because they are decisions taken while the world runs: the participants removed
around the ego's start when it enters, the over-speeding and rounding vehicles of abnormal scenarios
(chosen and steered through TraCI), the world's gridlock breaker (``sim.gridlock``: it removes a
participant that has stood in the junction too long), and of course the controller. Up to the ego's
entry the traffic is the world's own (unless the gridlock breaker acted during the warm-up); after
it, the SUMO-driven ego changes what the others do.
"""

from __future__ import annotations

import math
import shutil
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from crossroads.constants import EGO_LENGTH_M, EGO_WIDTH_M, SIM_STEP_S
from crossroads.geometry import project_onto_polyline
from crossroads.scenario.spec import ScenarioSpec, to_world_config
from crossroads.sim.abnormal import junction_lane_sets
from crossroads.sim.config import WorldConfig
from crossroads.sim.signals import TlProgram, phase_at
from crossroads.sim.sumo import SumoSession
from crossroads.sim.traffic import write_plan
from crossroads.sim.world import EGO_ID, ROUTE_MARGIN_S, World

EGO_VTYPE = "ego"


@dataclass(frozen=True)
class EpisodeSeeds:
    """The seeds the world derives from an episode seed (``World.reset``: one child of
    ``SeedSequence(seed)`` each for the traffic, SUMO, the abnormal vehicles and the noise)."""

    traffic: int
    sumo: int

    @classmethod
    def of(cls, seed: int) -> EpisodeSeeds:
        traffic_seq, sumo_seq, _, _ = np.random.SeedSequence(seed).spawn(4)
        return cls(int(traffic_seq.generate_state(1)[0]), int(sumo_seq.generate_state(1)[0] % 2**31))


@dataclass(frozen=True)
class Bundle:
    """The files of an exported bundle."""

    directory: Path
    config: Path
    net: Path
    routes: Path
    ego_routes: Path
    additional: Path
    seed: int

    def files(self) -> list[Path]:
        return [self.config, self.net, self.routes, self.ego_routes, self.additional]


def unrolled_phases(program: TlProgram, *, switch_s: float, phase_index: int, elapsed_s: float,
                    end_s: float) -> list[tuple[float, str]]:
    """(duration, state) of the light from t = 0 to ``end_s``: the net's program until ``switch_s``,
    then phase ``phase_index`` with ``elapsed_s`` already spent, cycling on with the program's
    durations (what ``apply_start`` makes of it)."""
    out: list[tuple[float, str]] = []
    t = 0.0
    while t < switch_s - 1e-9:
        at = phase_at(program, t)
        left = min(at.remaining_s, switch_s - t)
        out.append((left, program.phases[at.index].state))
        t += left
    index, left = phase_index, program.phases[phase_index].duration_s - elapsed_s
    while t < end_s - 1e-9:
        out.append((left, program.phases[index].state))
        t += left
        index = (index + 1) % len(program.phases)
        left = program.phases[index].duration_s
    return out


def _additional(program: TlProgram, phases: list[tuple[float, str]], inside: list[str], outside: list[str],
                limits: tuple[float, float]) -> str:
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', "<additional>",
             "    <!-- the light of the episode: the net's program during the warm-up, then the scenario's "
             "phase and offset (crossroads.sim.signals.apply_start) -->",
             f'    <tlLogic id={quoteattr(program.tl_id)} programID="crossroads" type="static" offset="0">']
    lines += [f'        <phase duration="{d:.3f}" state={quoteattr(s)}/>' for d, s in phases]
    lines.append("    </tlLogic>")
    lines.append("    <!-- the speed limits of SPEC §8 on the junction's lanes (crossroads.sim.abnormal) -->")
    for name, lanes, speed in (("inside", inside, limits[0]), ("outside", outside, limits[1])):
        if lanes:
            lines.append(f'    <variableSpeedSign id="crossroads_limit_{name}" lanes={quoteattr(" ".join(lanes))}>')
            lines.append(f'        <step time="0" speed="{speed:.6f}"/>')
            lines.append("    </variableSpeedSign>")
    lines.append("</additional>")
    return "\n".join(lines) + "\n"


def _ego_routes(config: WorldConfig, route_edges: list[str], lane_index: int, depart_pos_m: float) -> str:
    start = config.ego_start
    return "\n".join([
        '<?xml version="1.0" encoding="UTF-8"?>', "<routes>",
        "    <!-- the ego where the scenario starts it, when the warm-up ends; SUMO's own model drives it. "
        "No speed distribution: drawing its speed factor would shift SUMO's random numbers, and the traffic's -->",
        f'    <vType id="{EGO_VTYPE}" vClass="passenger" length="{EGO_LENGTH_M:g}" width="{EGO_WIDTH_M:g}" '
        'color="red" sigma="0" speedFactor="1" speedDev="0"/>',
        f'    <vehicle id="{EGO_ID}" type="{EGO_VTYPE}" depart="{config.warmup_s:.2f}" departLane="{lane_index}" '
        f'departPos="{depart_pos_m:.2f}" departSpeed="{start.speed_mps:.3f}">',
        f'        <route edges={quoteattr(" ".join(route_edges))}/>',
        "    </vehicle>", "</routes>", ""])


def _sumocfg(args: tuple[str, ...], files: dict[str, str], end_s: float) -> str:
    """A configuration of SUMO's command line ``args`` (its own files replaced by the bundle's)."""
    options: dict[str, str] = {}
    tokens = list(args[1:])
    for k in range(0, len(tokens), 2):
        options[tokens[k].lstrip("-")] = tokens[k + 1]
    options.update(files)
    options["end"] = f"{end_s:g}"
    groups = {"input": ("net-file", "route-files", "additional-files"),
              "time": ("begin", "end", "step-length"),
              "random_number": ("seed",)}
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', "<configuration>"]
    placed: set[str] = set()
    for group, keys in groups.items():
        lines.append(f"    <{group}>")
        for key in keys:
            if key in options:
                lines.append(f"        <{key} value={quoteattr(options[key])}/>")
                placed.add(key)
        lines.append(f"    </{group}>")
    lines.append("    <!-- the world's other options (crossroads.sim.sumo.SumoSession.start) -->")
    lines.append("    <processing>")
    lines += [f"        <{k} value={quoteattr(v)}/>" for k, v in options.items() if k not in placed]
    lines.append("    </processing>")
    lines.append("</configuration>")
    return "\n".join(lines) + "\n"


def export_bundle(spec: ScenarioSpec, seed: int, out_dir: Path, *, base_dir: str | Path | None = None) -> Bundle:
    """Write the SUMO bundle of episode ``seed`` of ``spec`` into ``out_dir`` (module docstring)."""
    config = to_world_config(spec, base_dir=base_dir)
    seeds = EpisodeSeeds.of(seed)
    # what the world decides before it starts SUMO: one place for it (the world's own set-up)
    world = World(config)
    try:
        junction, program = world.junction, world.program
        phase_index, elapsed_s = world.start_phase  # the light at the ego's entry
        placement = world.placement  # where and on which route the ego enters
        demand = world.drawn_demand(seeds.traffic)  # with the injected over-speeders
    finally:
        world.close()

    out_dir.mkdir(parents=True, exist_ok=True)
    name = spec.name
    paths = {"net": out_dir / f"{name}.net.xml", "routes": out_dir / f"{name}.rou.xml",
             "ego": out_dir / f"{name}.ego.rou.xml", "additional": out_dir / f"{name}.add.xml",
             "config": out_dir / f"{name}.sumocfg"}
    shutil.copyfile(config.net_file, paths["net"])
    end_s = config.warmup_s + config.timeout_s
    write_plan(demand, paths["routes"])
    # SUMO as the world starts it: its command line, every lane (internal ones included), and the
    # lane the ego departs on
    depart_lane = f"{placement.route_edges[0]}_{placement.depart_lane}"
    session = SumoSession()
    with session.start(paths["net"], [paths["routes"]], seed=seeds.sumo, step_length_s=SIM_STEP_S):
        args, lane_ids, shape = session.args, session.lane_ids(), session.lane_shape(depart_lane)
    inside, outside = junction_lane_sets(junction, lane_ids) if config.abnormal.apply_limits else (set(), set())
    # the world warms up round(warmup / step) steps, then sets the light (World.reset)
    phases = unrolled_phases(program, switch_s=int(round(config.warmup_s / SIM_STEP_S)) * SIM_STEP_S,
                             phase_index=phase_index, elapsed_s=elapsed_s, end_s=end_s + ROUTE_MARGIN_S)
    paths["additional"].write_text(_additional(program, phases, sorted(inside), sorted(outside),
                                               (config.abnormal.limit_inside_mps, config.abnormal.limit_outside_mps)),
                                   encoding="utf-8")
    half = EGO_LENGTH_M / 2.0  # SUMO places a vehicle by its front bumper
    front = (placement.x + half * math.cos(placement.heading_rad), placement.y + half * math.sin(placement.heading_rad))
    _, depart_pos, _ = project_onto_polyline(shape, front)
    paths["ego"].write_text(_ego_routes(config, list(placement.route_edges), placement.depart_lane, depart_pos),
                            encoding="utf-8")
    files = {"net-file": paths["net"].name, "route-files": f"{paths['routes'].name},{paths['ego'].name}",
             "additional-files": paths["additional"].name}
    paths["config"].write_text(_sumocfg(args, files, end_s), encoding="utf-8")
    return Bundle(out_dir, paths["config"], paths["net"], paths["routes"], paths["ego"], paths["additional"], seed)
