"""ONNX policies: the contract checked at load time, driving an episode, the shipped APG exported."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import onnx
import pytest
import yaml
from onnx import TensorProto, helper, numpy_helper

from crossroads.constants import STATE_DIM
from crossroads.evaluation.episode import run_episode
from crossroads.evaluation.executors import EpisodeTask, ProcessExecutor, WorkerJob
from crossroads.evaluation.onnx_policy import OnnxError, OnnxNetworks, trial_states
from crossroads.policy.ref import PolicyError, parse_policy
from crossroads.evaluation.policies import load_controller
from crossroads.scenario.spec import load_scenario, run_seeds, to_world_config
from crossroads.idc.state import DPHI, DV, DY
from crossroads.sim.world import World

from support import REPO_ROOT

TINY = {"version": 1, "name": "tiny-left", "intersection": "a_single_lane", "task": "left",
        "traffic": {"vehicles_per_hour": 200, "cyclists_per_hour": 50, "pedestrians_per_hour": 50},
        "warmup_s": 5.0, "timeout_s": 12.0, "runs": 3, "seed": 7}


def linear_policy(width: int = STATE_DIM, *, value: bool = True, batch: str | int = "batch",
                  elem: int = TensorProto.FLOAT, action_width: int = 2, extra_input: bool = False) -> bytes:
    """A small hand-made policy: action = state @ W + b (steer on Δy and Δφ, brake on Δv), value = Δy²."""
    dtype = np.float32 if elem == TensorProto.FLOAT else np.float64
    w = np.zeros((width, action_width), dtype)
    w[DY, 0], w[DPHI, 0], w[DV, 1] = -0.3, -1.0, -0.8
    nodes = [helper.make_node("MatMul", ["state", "W"], ["raw"]), helper.make_node("Add", ["raw", "b"], ["action"])]
    inits = [numpy_helper.from_array(w, "W"), numpy_helper.from_array(np.zeros(action_width, dtype), "b")]
    outputs = [helper.make_tensor_value_info("action", elem, [batch, action_width])]
    if value:
        pick = np.zeros((width, 1), dtype)
        pick[DY, 0] = 1.0
        nodes += [helper.make_node("MatMul", ["state", "pick"], ["dy"]), helper.make_node("Mul", ["dy", "dy"], ["value"])]
        inits.append(numpy_helper.from_array(pick, "pick"))
        outputs.append(helper.make_tensor_value_info("value", elem, [batch, 1]))
    inputs = [helper.make_tensor_value_info("state", elem, [batch, width])]
    if extra_input:
        inputs.append(helper.make_tensor_value_info("other", elem, [batch, 1]))
    graph = helper.make_graph(nodes, "linear", inputs, outputs, inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    return model.SerializeToString()


@pytest.fixture
def tiny(tmp_path: Path) -> Path:
    path = tmp_path / "tiny-left.yaml"
    path.write_text(yaml.safe_dump(TINY))
    return path


def test_the_signature_is_read_from_the_graph() -> None:
    nets = OnnxNetworks(linear_policy())
    sig = nets.signature
    assert (sig.input_name, sig.state_width, sig.batched, sig.action_output, sig.value_output) == (
        "state", STATE_DIM, True, "action", "value")
    states = trial_states(STATE_DIM)
    np.testing.assert_allclose(nets.values(states), states[:, DY] ** 2, rtol=1e-6)
    assert nets.actions(states).shape == (len(states), 2)
    one = OnnxNetworks(linear_policy(batch=1, value=False, elem=TensorProto.DOUBLE))  # one row per run
    assert not one.signature.batched and one.signature.value_output is None
    assert one.actions(states).shape == (len(states), 2) and one.values(states) is None


@pytest.mark.parametrize(("data", "message"), [
    (b"certainly not protobuf \xff\xfe", "not an ONNX model"),
    (linear_policy(width=100), r"shape \(batch, 100\); the IDC state is \(batch, 108 or 120\)"),
    (linear_policy(batch=4), "fixed batch of 4"),
    (linear_policy(action_width=3),
     r"output 'action' has shape \(batch, 3\); the action is \(batch, 2\)"),
    (linear_policy(extra_input=True), "takes 2 inputs"),
])
def test_a_model_that_does_not_fit_the_state_layout_is_refused_clearly(data: bytes, message: str) -> None:
    with pytest.raises(OnnxError, match=message):
        OnnxNetworks(data)


def test_checker_integer_states_and_external_data_are_refused(tmp_path: Path) -> None:
    model = onnx.load_model_from_string(linear_policy())
    model.graph.node[0].op_type = "NoSuchOperator"
    with pytest.raises(OnnxError, match="onnx.checker refused the model"):
        OnnxNetworks(model.SerializeToString())
    ints = onnx.load_model_from_string(linear_policy())
    ints.graph.input[0].type.tensor_type.elem_type = TensorProto.INT64
    with pytest.raises(OnnxError, match="element type INT64"):
        OnnxNetworks(ints.SerializeToString())
    external = onnx.load_model_from_string(linear_policy())
    onnx.save_model(external, tmp_path / "ext.onnx", save_as_external_data=True, all_tensors_to_one_file=True,
                    location="weights.bin", size_threshold=0)
    with pytest.raises(OnnxError, match="external files"):
        OnnxNetworks((tmp_path / "ext.onnx").read_bytes())


def test_an_onnx_policy_drives_an_episode_with_and_without_value(tmp_path: Path, tiny: Path) -> None:
    spec = load_scenario(tiny)
    with World(to_world_config(spec, base_dir=tiny.parent)) as world:
        for name, data in (("valued", linear_policy()), ("plain", linear_policy(value=False))):
            path = tmp_path / f"{name}.onnx"
            path.write_bytes(data)
            for text in (f"onnx:{path}", f"onnx:{path}+shield"):
                controller = load_controller(parse_policy(text))
                assert controller.name == name + ("+shield" if text.endswith("+shield") else "")
                result = run_episode(world, controller, run_seeds(spec, 1)[0])
                assert result.outcome in ("passed", "collision", "red_light", "off_road", "timeout")
                assert result.steps > 10
    (tmp_path / "bad.onnx").write_bytes(linear_policy(width=12))
    with pytest.raises(PolicyError, match=r"policy 'onnx:.*bad.onnx': input 'state' has shape"):
        load_controller(parse_policy(f"onnx:{tmp_path / 'bad.onnx'}"))


@pytest.mark.slow
def test_the_shipped_apg_exported_to_onnx_ends_every_episode_as_the_checkpoint(tmp_path: Path) -> None:
    """A few seeds of the nominal left turn, each in a forked worker episode (as a batch runs them):
    the same outcome, steps and travel time. The 50-seed comparison: benchmarks/onnx_parity.py."""
    from crossroads.rl.onnx_export import export_policy_onnx

    model = REPO_ROOT / "models" / "apg.pt"
    exported = export_policy_onnx(model, tmp_path / "apg.onnx")
    spec = load_scenario(REPO_ROOT / "scenarios" / "nominal" / "a_single_lane-left.yaml")
    spec = spec.model_copy(update={"warmup_s": 30.0, "timeout_s": 15.0})
    tasks = [EpisodeTask(i, s) for i, s in enumerate(run_seeds(spec, 3))]
    results = {}
    for ref in (str(model), f"onnx:{exported}"):
        job = WorkerJob(spec=spec.model_dump(mode="json"), base_dir=None, policy_ref=ref, traces="none")
        reports: list = []
        ProcessExecutor(workers=1).run(job, tasks, reports.append, threading.Event())
        assert all(r.error is None for r in reports), [r.error for r in reports]
        results[ref] = [(r.result["outcome"], r.result["steps"], r.result["travel_time_s"])
                        for r in sorted(reports, key=lambda r: r.run_index)]
    assert results[str(model)] == results[f"onnx:{exported}"]
    assert len(set(results[str(model)])) > 1  # the seeds do differ


def test_identical_states_tie_to_the_first_path_however_the_values_round() -> None:
    """Candidate paths that share their first metres give the same state, hence the same value; a
    network that rounds row by row (torch's batched float32 products gave row 1 of 3 identical rows
    a few 1e-7 less, onnxruntime all three the same) must not pick the path: the first one drives."""
    import torch
    from torch import nn

    from crossroads.idc.decision import IdcController

    class RowRounding(nn.Module):
        """Δy², less 1e-7 per row: later rows of equal states look a rounding better."""

        def __init__(self) -> None:
            super().__init__()
            self.weight = nn.Parameter(torch.zeros(0), requires_grad=False)

        def forward(self, states: torch.Tensor) -> torch.Tensor:
            return states[:, DY] ** 2 - 1e-7 * torch.arange(len(states), dtype=states.dtype)

    class Steer(RowRounding):
        preview = False

        def mean_action(self, states: torch.Tensor) -> torch.Tensor:
            return torch.stack([-states[:, DY], torch.zeros(len(states))], dim=-1)

    controller = IdcController(Steer(), RowRounding())
    shared = np.repeat(trial_states(STATE_DIM, 1), 4, axis=0)
    shared[:, DY] = 0.1
    shared[3, DY] = 0.5  # the fourth path has already parted from the others
    best, _, values = controller.decide_states(shared)
    assert best == 0 and values[0] == values[1] == values[2] and values[3] > values[0]
    shared[2, DY] = 0.05  # now a different state, truly nearer its path: it wins by its value
    best, action, _ = controller.decide_states(shared)
    assert best == 2 and action[0] == pytest.approx(-0.05)


@pytest.mark.slow
def test_the_shipped_apg_and_its_onnx_export_decide_alike_with_the_shield(tmp_path: Path) -> None:
    """Step by step on the same observations (the checkpoint driving): the same path, speed mode and
    shield verdict, actions within float32 rounding, on seeded nominal left turns with three
    candidate paths that share their first metres (before the tie went to the first path, the two
    parted on the path at several steps of every episode). The outcome of 50 seeds, each runtime
    driving: benchmarks/onnx_parity.py --shield."""
    from crossroads.rl.onnx_export import export_policy_onnx

    model = REPO_ROOT / "models" / "apg.pt"
    exported = export_policy_onnx(model, tmp_path / "apg.onnx")
    spec = load_scenario(REPO_ROOT / "scenarios" / "nominal" / "c_three_lane-left.yaml")
    spec = spec.model_copy(update={"timeout_s": 12.0})
    checkpoint = load_controller(parse_policy(f"{model}+shield"))
    onnx_driver = load_controller(parse_policy(f"onnx:{exported}+shield"))
    steps, braked = 0, 0
    with World(to_world_config(spec)) as world:
        assert len(world.candidates) == 3
        for seed in run_seeds(spec, 4):
            observation, outcome = world.reset(seed), None
            checkpoint.reset(world.candidates)
            onnx_driver.reset(world.candidates)
            while outcome is None:
                ours, theirs = checkpoint.decide(observation), onnx_driver.decide(observation)
                assert (ours.path_index, ours.speed_mode, ours.shield_braking) == (
                    theirs.path_index, theirs.speed_mode, theirs.shield_braking), (seed, steps)
                np.testing.assert_allclose(theirs.action, ours.action, atol=1e-4)
                observation, outcome = world.step(ours.action)
                steps, braked = steps + 1, braked + bool(ours.shield_braking)
    assert steps > 200 and braked > 0  # the shield did step in
