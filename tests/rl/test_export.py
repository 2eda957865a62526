"""Shipping a trained run: a small model file that drives like its checkpoint, and its card."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import torch
from typer.testing import CliRunner

from crossroads.evaluation.policies import load_controller
from crossroads.policy.ref import parse_policy
from crossroads.rl.checkpoint import find_checkpoint, load_networks
from crossroads.rl.cli import app
from crossroads.rl.train import train

from rl.rl_support import make_batch
from rl.test_train import tiny


def test_export_keeps_the_networks_and_writes_a_card(tmp_path: Path, path_set, model) -> None:
    run = train(tiny(tmp_path, iterations=3, run_name="apg"))
    out = tmp_path / "models" / "apg.pt"
    result = CliRunner().invoke(app, ["export", str(run), "-o", str(out), "--note", "passes 0 of 0",
                                      "--note", "second line"])
    assert result.exit_code == 0, result.output

    shipped, config = load_networks(out)
    trained, _ = load_networks(run)
    states = model.initial_states(make_batch(path_set, 6, seed=2))
    assert torch.equal(shipped.policy.mean_action(states), trained.policy.mean_action(states))
    assert torch.equal(shipped.value(states), trained.value(states))
    assert out.stat().st_size < find_checkpoint(run).stat().st_size  # no optimisers, no buffer

    card = json.loads(out.with_suffix(".card.json").read_text())
    assert card["algo"] == "apg" and card["iterations_done"] == 3
    assert {"losses/J_pi", "charts/TAR"} <= set(card["final"])
    assert card["hardware"]["torch"] == torch.__version__ and card["wall_time_s"] > 0
    assert card["paper_iterations"] == 200_000 and card["fraction_of_paper"] == round(3 / 200_000, 4)
    assert card["notes"] == ["passes 0 of 0", "second line"]
    # the tiny test config differs from the paper's in its network size, among others
    assert card["changed_from_defaults"]["hidden_units"]["default"] == 256
    assert "algo" not in card["changed_from_defaults"] and "out" not in card["changed_from_defaults"]
    assert load_controller(parse_policy(str(out))).name == "apg"  # drives as --policy models/apg.pt
    shielded = load_controller(parse_policy(str(out) + "+shield"))  # ... and as --policy models/apg.pt+shield
    assert shielded.name == "apg+shield" and shielded.shield  # type: ignore[attr-defined]

    missing = CliRunner().invoke(app, ["export", str(tmp_path / "nowhere"), "-o", str(out)])
    assert missing.exit_code == 2 and "no checkpoint" in missing.output


@pytest.mark.slow
def test_warm_start_from_an_exported_model(tmp_path: Path, path_set, model) -> None:
    from crossroads.rl.learner import Learner
    from crossroads.rl.train import warm_start

    run = train(tiny(tmp_path, iterations=3, run_name="first"))
    out = tmp_path / "apg.pt"
    CliRunner().invoke(app, ["export", str(run), "-o", str(out)])
    learner = Learner(tiny(tmp_path, init_from=out), model, torch.device("cpu"))
    warm_start(learner, out)
    shipped, _ = load_networks(out)
    for mine, theirs in zip(learner.nets, shipped, strict=True):
        assert all(torch.equal(a, b) for a, b in zip(mine.state_dict().values(),
                                                      theirs.state_dict().values(), strict=True))
    second = train(tiny(tmp_path, iterations=3, run_name="second", init_from=out))
    assert (second / "metrics.csv").is_file()

    # the second model's card counts the first run's iterations and wall time (across sessions)
    first_card = json.loads(out.with_suffix(".card.json").read_text())
    again = tmp_path / "again.pt"
    assert CliRunner().invoke(app, ["export", str(second), "-o", str(again)]).exit_code == 0
    card = json.loads(again.with_suffix(".card.json").read_text())
    assert card["iterations_done"] == 3 and card["iterations_total"] == 6
    assert card["fraction_of_paper"] == round(6 / 200_000, 4)
    assert [h["iterations"] for h in card["lineage"]] == [3] and card["lineage"][0]["model"] == str(out)
    assert abs(card["wall_time_total_s"] - (card["wall_time_s"] + first_card["wall_time_s"])) <= 0.11
    # a third generation keeps the whole history, oldest first
    third = train(tiny(tmp_path, iterations=2, run_name="third", init_from=again))
    last = tmp_path / "third.pt"
    CliRunner().invoke(app, ["export", str(third), "-o", str(last)])
    card = json.loads(last.with_suffix(".card.json").read_text())
    assert [h["model"] for h in card["lineage"]] == [str(out), str(again)]
    assert card["iterations_total"] == 8
    # the warm start's file gone by export time: the export still works and says so
    again.unlink()
    assert CliRunner().invoke(app, ["export", str(third), "-o", str(last)]).exit_code == 0
    card = json.loads(last.with_suffix(".card.json").read_text())
    assert card["lineage"] == [{"model": str(again), "algo": None, "iterations": 0, "wall_time_s": None,
                                "changed_from_defaults": {}, "missing": True}]


@pytest.mark.parametrize(("preview", "lead", "encoder"), [(False, False, 0), (True, False, 0), (True, True, 0),
                                                     (True, True, 8)],
                         ids=["paper-state", "path-preview", "preview-and-lead", "pooled-participants"])
def test_onnx_export_equals_torch(tmp_path: Path, path_set, preview: bool, lead: bool, encoder: int) -> None:
    from crossroads.rl.idc_model import IDCModel
    from crossroads.rl.onnx_export import check_onnx, export_onnx

    run = train(tiny(tmp_path, iterations=3, run_name="onnx", path_preview=preview, lead_input=lead,
                     participant_encoder=encoder))
    policy_path, value_path = export_onnx(run, tmp_path / "onnx")
    model = IDCModel(path_set.tensors(), preview=preview)
    states = model.initial_states(make_batch(path_set, 64, seed=3)).numpy()
    assert states.shape[1] == (120 if preview else 108)
    action_err, value_err = check_onnx(run, policy_path, value_path, states)
    assert action_err <= 1e-5 and value_err <= 1e-5
    result = CliRunner().invoke(app, ["onnx", str(run), "-o", str(tmp_path / "cli")])
    assert result.exit_code == 0, result.output
    assert "max |onnx - torch| / max(1, |torch|)" in result.output
    # MODEL.onnx: both networks in one graph, what --policy onnx:PATH drives with
    from crossroads.evaluation.onnx_policy import OnnxNetworks

    combined = OnnxNetworks((tmp_path / "cli" / f"{run.stem}.onnx").read_bytes())
    nets, _ = load_networks(run)
    with torch.no_grad():
        x = torch.as_tensor(states, dtype=torch.float32)
        np.testing.assert_allclose(combined.actions(states), nets.policy.mean_action(x).numpy(), atol=1e-5)
        np.testing.assert_allclose(combined.values(states), nets.value(x).numpy(), rtol=1e-5, atol=1e-5)


def test_describe_cpu_names_the_model_and_its_vector_extensions() -> None:
    from crossroads.rl.export import describe_cpu

    cpuinfo = ("processor\t: 0\nmodel name\t: AMD EPYC\nflags\t\t: fpu sse2 avx fma avx2 sha_ni\n\n"
               "processor\t: 1\nmodel name\t: AMD EPYC\nflags\t\t: fpu sse2 avx fma avx2 sha_ni\n")
    assert describe_cpu(cpuinfo) == "AMD EPYC (avx2)"
    assert describe_cpu("model name : Xeon\nflags : avx2 avx512f amx_tile\n") == "Xeon (avx2, avx512f, amx_tile)"
    assert describe_cpu("model name : Old\nflags : sse2\n") == "Old (no avx2)"
    assert describe_cpu("processor : 0\n") == ""


class _Planted:
    """Pickles as a call that writes a file: what opening a hostile checkpoint must never do."""

    def __init__(self, target: Path) -> None:
        self.target = target

    def __reduce__(self) -> tuple[object, tuple[str, str]]:
        import pathlib

        return (pathlib.Path.touch, (str(self.target),))  # type: ignore[return-value]


def test_checkpoints_are_read_as_plain_data_only(tmp_path: Path) -> None:
    """Files are opened with torch.load(weights_only=True): a pickle that would run code is refused
    before it runs; numpy arrays and RNG states survive the plain format exactly; an older file of
    numpy pickles is refused with the way to convert it, and converts."""
    import numpy as np

    from crossroads.rl.checkpoint import (
        UnsafeCheckpointError,
        convert_legacy,
        load_checkpoint,
        rng_states,
        save_checkpoint,
    )

    planted = tmp_path / "ran-code"
    hostile = tmp_path / "hostile.pt"
    torch.save({"format": 1, "iteration": 0, "config": {}, "x": _Planted(planted)}, hostile)
    with pytest.raises(UnsafeCheckpointError, match="plain data"):
        load_checkpoint(hostile)
    assert not planted.exists()

    state = rng_states()
    buffer = {"obs": np.arange(12, dtype=np.float32).reshape(3, 4), "flags": np.array([True, False]),
              "rng": np.random.default_rng(5).bit_generator.state, "scale": np.float64(0.25)}
    path = save_checkpoint(tmp_path / "run", 7, {"config": {"algo": "apg"}, "rng": state, "buffer": buffer,
                                                   "sampler": {"pending": (3, {"w": np.ones((2, 2))})}})
    back = load_checkpoint(path)
    assert back["iteration"] == 7 and back["config"] == {"algo": "apg"}
    np.testing.assert_array_equal(back["rng"]["numpy"][1], state["numpy"][1])
    assert back["rng"]["numpy"][0] == "MT19937" and back["rng"]["python"] == state["python"]
    assert torch.equal(back["rng"]["torch"], state["torch"])
    assert back["buffer"]["obs"].dtype == np.float32 and back["buffer"]["obs"].tolist() == buffer["obs"].tolist()
    assert back["buffer"]["flags"].tolist() == [True, False] and back["buffer"]["scale"] == 0.25
    assert back["buffer"]["rng"] == buffer["rng"]
    pending = back["sampler"]["pending"]
    assert isinstance(pending, tuple) and pending[0] == 3 and pending[1]["w"].tolist() == [[1.0, 1.0], [1.0, 1.0]]

    legacy = tmp_path / "legacy.pt"
    torch.save({"format": 1, "iteration": 2, "config": {}, "buffer": {"obs": np.arange(3)}}, legacy)
    with pytest.raises(UnsafeCheckpointError, match="convert"):
        load_checkpoint(legacy)
    convert_legacy(legacy)
    assert load_checkpoint(legacy)["buffer"]["obs"].tolist() == [0, 1, 2]


@pytest.mark.parametrize("name", ["apg", "dpg"])
def test_shipped_models_load_as_plain_data(name: str) -> None:
    from support import REPO_ROOT

    from crossroads.rl.checkpoint import load_checkpoint

    path = REPO_ROOT / "models" / f"{name}.pt"
    data = torch.load(path, map_location="cpu", weights_only=True)  # what load_checkpoint does
    assert isinstance(data["config"], dict) and data["config"]["algo"] == name
    nets, config = load_networks(path)
    assert config.algo == name and nets.policy is not None
    assert load_checkpoint(path)["iteration"] == data["iteration"]
