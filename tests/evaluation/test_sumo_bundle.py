"""`crossroads export`: the bundle holds the world's inputs, and sumo runs it with the world's traffic."""

from __future__ import annotations

import math
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import sumo
import yaml
from typer.testing import CliRunner

from crossroads.cli import app
from crossroads.scenario.spec import load_scenario, to_world_config
from crossroads.evaluation.sumo_bundle import EpisodeSeeds, export_bundle
from crossroads.network.junction import read_junction
from crossroads.sim.abnormal import AbnormalTraffic
from crossroads.sim.signals import apply_start, read_program
from crossroads.sim.sumo import SumoSession
from crossroads.sim.world import World

SCENARIO = {  # a short warm-up, a light that starts mid-phase elsewhere in the cycle, an over-speeder
    "version": 1, "name": "bundle-left", "intersection": "a_single_lane", "task": "left",
    "lights": {"phase": 4, "elapsed_s": 20.0}, "warmup_s": 20.0, "timeout_s": 10.0, "runs": 2, "seed": 3,
    "abnormal": {"injection": {"arrive_s": 5.0, "excess": 0.3}},
}
SEED = 1705482282


@pytest.fixture
def scenario(tmp_path: Path) -> Path:
    path = tmp_path / "bundle-left.yaml"
    path.write_text(yaml.safe_dump(SCENARIO))
    return path


def _options(args: tuple[str, ...]) -> dict[str, str]:
    tokens = list(args[1:])
    return {tokens[k].lstrip("-"): tokens[k + 1] for k in range(0, len(tokens), 2)}


def test_the_bundle_holds_the_inputs_the_world_gives_sumo(scenario: Path, tmp_path: Path) -> None:
    spec = load_scenario(scenario)
    bundle = export_bundle(spec, SEED, tmp_path / "bundle", base_dir=scenario.parent)
    with World(to_world_config(spec, base_dir=scenario.parent)) as world:
        world.reset(SEED)
        used = _options(world.session.args)
        world_routes = Path(used["route-files"]).read_bytes()
    assert bundle.routes.read_bytes() == world_routes  # the same seeded demand, byte for byte
    assert b'<trip id="inj0"' in world_routes and b'speedFactor="1.3000"' in world_routes
    config = ET.parse(bundle.config).getroot()
    written = {el.tag: el.get("value") for el in config.iter() if el.get("value") is not None}
    assert written["seed"] == used["seed"] == str(EpisodeSeeds.of(SEED).sumo)
    for key, value in used.items():
        if key not in ("net-file", "route-files", "additional-files"):
            assert written[key] == value, key
    assert written["end"] == "30"
    ego = ET.parse(bundle.ego_routes).getroot().find("vehicle")
    assert ego is not None and ego.get("depart") == "20.00" and ego.get("departSpeed") == "8.333"


def test_sumo_runs_the_bundle_headless_with_the_worlds_traffic(scenario: Path, tmp_path: Path) -> None:
    """`sumo -c` (the eclipse-sumo wheel's binary) on the bundle: the same vehicles at the same
    places at the end of the warm-up as the world's SUMO (the §8 limits set through TraCI), the same
    light as apply_start makes it after, and the ego entering where the scenario starts it."""
    spec = load_scenario(scenario)
    bundle = export_bundle(spec, SEED, tmp_path / "bundle", base_dir=scenario.parent)
    tls_out = tmp_path / "tls.add.xml"
    config = to_world_config(spec, base_dir=scenario.parent)
    junction = read_junction(config.net_file)
    tls_out.write_text(f'<additional><timedEvent type="SaveTLSStates" source="{junction.tl_id}" '
                       f'dest="{tmp_path / "tls.xml"}"/></additional>')
    binary = Path(sumo.SUMO_HOME) / "bin" / "sumo"
    done = subprocess.run([str(binary), "-c", str(bundle.config), "--end", "25",
                           "--additional-files", f"{bundle.additional},{tls_out}",
                           "--fcd-output", str(tmp_path / "fcd.xml")], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    fcd = {float(step.get("time")): {v.get("id"): (float(v.get("x")), float(v.get("y"))) for v in step}
           for step in ET.parse(tmp_path / "fcd.xml").getroot()}
    lights = {round(float(s.get("time")), 1): s.get("state") for s in ET.parse(tmp_path / "tls.xml").getroot()}

    # the world's SUMO up to the ego's entry, the same way World.reset drives it
    program = read_program(config.net_file, junction.tl_id)
    seeds = EpisodeSeeds.of(SEED)
    session = SumoSession()
    with session.start(config.net_file, [bundle.routes], seed=seeds.sumo):
        AbnormalTraffic(junction, junction.default_approach(), config.abnormal, 0).apply_speed_limits(session)
        session.step(199)
        snap = session.snapshot()
        expected = {str(i): (x, y) for i, x, y in zip(snap.ids, snap.x, snap.y, strict=True)}
        heads = {str(i): (h, n) for i, h, n in zip(snap.ids, snap.heading, snap.length, strict=True)}
        session.step()
        apply_start(session, program, 4, 20.0)
        world_lights = {}
        for _ in range(50):
            session.step()
            world_lights[round(session.time_s, 1)] = session.tl_state(junction.tl_id)
    # SUMO writes a step's outputs under the time the step began: libsumo's state at 19.9 s (199
    # steps) is the fcd's at 19.8 s
    at_end = fcd[19.8]
    assert len(expected) > 10 and set(at_end) == set(expected)
    for pid, (x, y) in expected.items():  # fcd: the front's middle, rounded to the cm
        h, length = heads[pid]
        fx, fy = x + 0.5 * length * math.cos(h), y + 0.5 * length * math.sin(h)
        assert at_end[pid] == pytest.approx((fx, fy), abs=0.011), pid
    compared = [(lights[round(t - 0.1, 1)], state) for t, state in world_lights.items() if t <= 25.0]
    assert len(compared) == 50 and all(a == b for a, b in compared)
    assert len({state for _, state in compared}) > 1  # the light changed in between: phase 4 ends 3 s after the entry
    ego = [pos for t, ids in sorted(fcd.items()) if t >= 20.0 for pid, pos in ids.items() if pid == "ego"]
    assert ego, "the ego entered"


def test_cli_export_writes_the_bundle(scenario: Path, tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["export", str(scenario), "--seed", str(SEED), "-o", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    assert f"seed {SEED}: sumo-gui -c" in result.output
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "bundle-left.add.xml", "bundle-left.ego.rou.xml", "bundle-left.net.xml", "bundle-left.rou.xml",
        "bundle-left.sumocfg"]
