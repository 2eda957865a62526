"""Training end to end on a tiny budget: files, determinism, exact resume, reloadable policies, CLI."""

from __future__ import annotations

import csv
import shutil
from dataclasses import replace
from pathlib import Path

import pytest
import torch
from typer.testing import CliRunner

from crossroads.rl.checkpoint import load_checkpoint, load_networks
from crossroads.rl.cli import app
from crossroads.rl.config import TrainConfig, apply_overrides
from crossroads.rl.train import RunExistsError, train

from rl.rl_support import INTERSECTION, make_batch


def tiny(out: Path, **kw) -> TrainConfig:
    base = TrainConfig(
        iterations=6, batch_size=8, horizon=5, hidden_layers=2, hidden_units=32, workers=0,
        intersections=(INTERSECTION,), tasks=("left",), learning_starts=8, samples_per_iteration=8,
        rule_rounds=1, max_episode_steps=30, warmup_s=5.0, log_every=3, checkpoint_every=3,
        tar_runs=1, tar_steps=10, out=out, progress=False, tensorboard=False)
    return replace(base, **kw)


def final_state(run_dir: Path) -> dict:
    return load_checkpoint(run_dir)["learner"]


def same_parameters(a: dict, b: dict) -> bool:
    return all(torch.equal(a[net][k], b[net][k]) for net in ("policy", "value", "adversary") for k in a[net])


def metric_rows(run_dir: Path) -> list[dict]:
    with (run_dir / "metrics.csv").open() as f:
        rows = list(csv.DictReader(f))
    for r in rows:  # timing differs run to run
        r.pop("charts/iterations_per_s")
        r.pop("time/elapsed_s")
    return rows


def test_smoke_run_with_one_worker_process(tmp_path: Path) -> None:
    run = train(tiny(tmp_path, workers=1, run_name="smoke"))
    rows = metric_rows(run)
    assert [int(r["iteration"]) for r in rows] == [3, 6]
    for key in ("losses/J_v", "losses/J_track", "losses/J_safe", "losses/J_pi", "charts/TAR"):
        assert all(r[key] != "" and float(r[key]) == float(r[key]) for r in rows), key
    assert (run / "checkpoints" / "ckpt_00000006.pt").is_file() and (run / "checkpoints" / "last.pt").is_file()
    assert (run / "config.json").is_file()
    with pytest.raises(RunExistsError):
        train(tiny(tmp_path, workers=1, run_name="smoke"))


def test_same_seed_same_parameters_and_resume_is_exact(tmp_path: Path) -> None:
    first = train(tiny(tmp_path, run_name="first"))
    second = train(tiny(tmp_path, run_name="second"))
    assert same_parameters(final_state(first), final_state(second))
    assert metric_rows(first) == metric_rows(second)
    other = train(tiny(tmp_path, run_name="other", seed=1))
    assert not same_parameters(final_state(first), final_state(other))

    # interrupt after iteration 3: keep only that checkpoint, then resume
    resumed = tmp_path / "resumed"
    shutil.copytree(first, resumed)
    ckpts = resumed / "checkpoints"
    (ckpts / "ckpt_00000006.pt").unlink()
    shutil.copyfile(ckpts / "ckpt_00000003.pt", ckpts / "last.pt")
    assert load_checkpoint(resumed)["iteration"] == 3
    train(tiny(tmp_path, run_name="resumed"), resume=True)
    assert load_checkpoint(resumed)["iteration"] == 6
    assert same_parameters(final_state(first), final_state(resumed))
    assert metric_rows(first) == metric_rows(resumed)


def test_dpg_run_and_a_loaded_checkpoint_reproduces_its_actions(tmp_path: Path, path_set, model) -> None:
    run = train(tiny(tmp_path, algo="dpg", iterations=3, run_name="dpg"))
    nets, config = load_networks(run)
    assert config.algo == "dpg" and nets.adversary is None
    again, _ = load_networks(run / "checkpoints" / "last.pt")
    s = model.initial_states(make_batch(path_set, 5, seed=4))
    assert torch.equal(nets.policy.mean_action(s), again.policy.mean_action(s))
    saved = load_checkpoint(run)["learner"]["policy"]
    assert all(torch.equal(saved[k], v) for k, v in nets.policy.state_dict().items())


def test_cli_overrides_and_plot(tmp_path: Path) -> None:
    cfg = apply_overrides(TrainConfig(), {"batch_size": "8", "tasks": "left,right", "max_grad_norm": "none",
                                          "policy_lr": "1e-3,1e-5", "sample_actions": "false"})
    assert cfg.batch_size == 8 and cfg.tasks == ("left", "right") and cfg.max_grad_norm is None
    assert cfg.policy_lr == (1e-3, 1e-5) and cfg.sample_actions is False
    with pytest.raises(ValueError, match="unknown training option"):
        apply_overrides(TrainConfig(), {"batchsize": "8"})
    with pytest.raises(ValueError, match="algo"):
        apply_overrides(TrainConfig(), {"algo": "ppo"})

    run = tmp_path / "run"
    run.mkdir()
    (run / "metrics.csv").write_text(
        "iteration,losses/J_v,losses/J_track,losses/J_safe,losses/J_pi,charts/TAR,charts/TAR_std,"
        "charts/lr_policy,charts/lr_value\n1,2,3,0,3,10,1,1e-4,3e-4\n2,1,2,0.1,3.5,9,1,5e-5,1e-4\n")
    out = tmp_path / "curves.png"
    result = CliRunner().invoke(app, ["plot", str(run), "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert out.stat().st_size > 1000
    bad = CliRunner().invoke(app, ["--set", "nope=1", "--out", str(tmp_path)])
    assert bad.exit_code == 2 and "unknown training option" in bad.output


def test_configs_from_before_xi_positions_are_refused_since_their_step_form_is_gone() -> None:
    """A run saved before either field existed trained with ξ added at every step, a form since
    removed: it is refused. A config saved now omits xi_positions but names nominal_floor: it loads."""
    old = TrainConfig(algo="apg").to_json()
    del old["nominal_floor"]
    with pytest.raises(ValueError, match=r"xi_positions='step': this experiment was removed"):
        TrainConfig.from_json(old)
    assert TrainConfig.from_json(TrainConfig().to_json()) == TrainConfig()


def test_configs_from_before_the_nominal_floor_keep_the_adversary_alone() -> None:
    """Runs saved before the nominal floor trained against the adversary's prediction alone; resumed, they still do."""
    old = {**TrainConfig(algo="apg").to_json(), "xi_positions": "offset"}  # as configs of the time named it
    del old["nominal_floor"]
    assert TrainConfig.from_json(old).nominal_floor is False
    assert TrainConfig.from_json(TrainConfig().to_json()).nominal_floor is True


def test_a_run_with_the_path_preview_warm_started_from_one_without_keeps_its_outputs_then_trains(
        tmp_path: Path, path_set) -> None:
    """Warm start into networks that read the path preview (TrainConfig.path_preview): the new inputs'
    weights start at zero, so the first decisions are the source's; then the run trains them, and its
    checkpoint drives through the online decision, which builds 120-value states for it."""
    from crossroads.idc.decision import IdcController
    from crossroads.idc.state import PREVIEW_STATE_DIM, STATE_DIM
    from crossroads.rl.idc_model import IDCModel
    from crossroads.rl.neural_nets import widen_first_layer

    source = train(tiny(tmp_path, iterations=3, run_name="plain"))
    plain, _ = load_networks(source)
    batch = make_batch(path_set, 6, seed=2)
    states = IDCModel(path_set.tensors(), preview=True).initial_states(batch)
    assert states.shape == (6, PREVIEW_STATE_DIM)
    assert torch.equal(states[:, :STATE_DIM], IDCModel(path_set.tensors()).initial_states(batch))

    preview_run = train(tiny(tmp_path, iterations=3, run_name="preview", path_preview=True, init_from=source))
    nets, config = load_networks(preview_run)
    assert config.path_preview and nets.policy.net[0].in_features == PREVIEW_STATE_DIM
    widened, _ = load_networks(source)
    from crossroads.rl.neural_nets import make_networks
    fresh = make_networks("apg", 2, 32, preview=True)
    fresh.policy.load_state_dict(widen_first_layer(widened.policy.state_dict(), fresh.policy))
    assert torch.allclose(fresh.policy.mean_action(states), plain.policy.mean_action(states[:, :STATE_DIM]))
    first = nets.policy.net[0].weight.detach()
    assert first[:, STATE_DIM:].abs().sum() > 0  # training gave the preview inputs weight
    with pytest.raises(ValueError, match="set path_preview"):  # and it cannot be dropped unnoticed
        train(tiny(tmp_path, iterations=1, run_name="narrow", init_from=preview_run))

    from crossroads.intersections import catalogue
    from crossroads.sim.config import WorldConfig
    from crossroads.sim.world import World
    controller = IdcController(nets.policy, nets.value)
    assert controller.preview
    with World(WorldConfig(net_file=catalogue.build(INTERSECTION), task="left", warmup_s=5.0)) as world:
        obs = world.reset(0)
        controller.reset(world.candidates)
        decision = controller.decide(obs)
    assert decision.action.shape == (2,) and len(decision.path_values) == len(world.candidates)


def test_a_run_logged_with_the_saturation_penalty_resumes_without_it(tmp_path: Path) -> None:
    """A checkpoint and metrics.csv written while ``losses/saturation`` was logged still resume."""
    from crossroads.rl.logging import COLUMNS, MetricsLogger
    from crossroads.rl.train import _Window

    (tmp_path / "metrics.csv").write_text("iteration,losses/J_pi,losses/saturation\n3,2.5,0.1\n6,2.0,0.2\n")
    MetricsLogger(tmp_path, resume_iteration=3, tensorboard=False).close()
    with (tmp_path / "metrics.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == COLUMNS and [(r["iteration"], r["losses/J_pi"]) for r in rows] == [("3", "2.5")]
    window = _Window.restore({"n": 2, "j_pi": 4.0, "saturated_share": 0.5, "saturation": 3.0, "elapsed": 1.0})
    assert (window.n, window.j_pi, window.saturated_share, window.elapsed) == (2, 4.0, 0.5, 1.0)
