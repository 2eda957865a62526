"""Named experiments on top of the paper's configuration, and the options of experiments that lost."""

from __future__ import annotations

import json
import re
from dataclasses import fields
from pathlib import Path

import pytest
import torch
from markdown.extensions.toc import slugify
from typer.testing import CliRunner

from crossroads.rl import train as train_module
from crossroads.rl.checkpoint import FORMAT, load_networks
from crossroads.rl.cli import app
from crossroads.rl.config import REMOVED_OPTIONS, TrainConfig, apply_overrides
from crossroads.rl.experiments import EXPERIMENTS, apply_experiments
from crossroads.rl.neural_nets import networks_for

from support import REPO_ROOT

KEPT_CARDS = ("models/apg.card.json", "models/dpg.card.json", "models/pooled/apg.card.json",
              "models/standing-car/apg.card.json")
RUN_FIELDS = {"algo", "iterations", "workers", "ray_address", "torch_threads", "device", "out", "run_name", "seed",
              "init_from", "log_every", "checkpoint_every", "progress", "tensorboard", "experiments"}
"""Fields a recipe leaves to the run: its length, machine, bookkeeping and warm-start file."""


def card_config(card: str) -> dict:
    return json.loads((REPO_ROOT / card).read_text())["config"]


def headings_of(page: Path) -> set[str]:
    """The anchors MkDocs gives the headings of a Markdown page."""
    return {slugify(title, "-") for title in re.findall(r"^#+ (.+)$", page.read_text(encoding="utf-8"), re.MULTILINE)}


def test_experiments_set_known_fields_and_are_recorded_in_order() -> None:
    known = {f.name for f in fields(TrainConfig)}
    for experiment in EXPERIMENTS.values():
        assert set(experiment.overrides) <= known - RUN_FIELDS, experiment.name
        assert apply_experiments(TrainConfig(), [experiment.name]) != TrainConfig()
    config = apply_experiments(TrainConfig(), ["short-run", "shipped-apg"])
    assert config.experiments == ("short-run", "shipped-apg")
    assert config.rule_share == 0.25 and config.policy_lr == (1e-4, 1e-5)  # the later one's own values
    assert apply_experiments(TrainConfig(), []) == TrainConfig()
    with pytest.raises(ValueError, match="unknown experiment 'paper'; known: short-run, shipped-apg, pooled"):
        apply_experiments(TrainConfig(), ["paper"])


@pytest.mark.parametrize(("name", "card"), [("shipped-apg", "models/apg.card.json"),
                                             ("pooled", "models/pooled/apg.card.json")])
def test_a_models_experiment_is_the_recipe_of_its_last_run(name: str, card: str) -> None:
    recipe = apply_experiments(TrainConfig(), [name]).to_json()
    ran = TrainConfig.from_json(card_config(card)).to_json()
    assert {k: (ran[k], recipe[k]) for k in ran if k not in RUN_FIELDS and ran[k] != recipe[k]} == {}


def test_short_run_is_what_the_training_script_applies() -> None:
    script = (REPO_ROOT / "scripts" / "train_models.sh").read_text()
    assert "RECIPE=(--experiment short-run)" in script
    config = apply_experiments(TrainConfig(), ["short-run"])
    assert config.policy_lr == config.value_lr == config.adversary_lr == (1e-3, 1e-5)
    assert (config.max_grad_norm, config.rule_share) == (10.0, 0.5)


def test_every_result_named_is_a_section_of_its_page() -> None:
    places = [e.measured for e in EXPERIMENTS.values()]
    places += [f"docs/tried/training.md#{removed.anchor}" for removed in REMOVED_OPTIONS.values()]
    for place in places:
        page, _, anchor = place.partition("#")
        assert anchor in headings_of(REPO_ROOT / page), place


@pytest.mark.parametrize("card", KEPT_CARDS)
def test_the_kept_models_configs_still_load(card: str) -> None:
    config = TrainConfig.from_json(card_config(card))
    assert set(config.experiments) <= set(EXPERIMENTS)


def test_removed_options_load_at_their_neutral_value_and_are_refused_otherwise() -> None:
    paper = TrainConfig().to_json()
    neutral = {name: removed.neutral for name, removed in REMOVED_OPTIONS.items()}
    assert TrainConfig.from_json({**paper, **neutral}) == TrainConfig()
    assert apply_overrides(TrainConfig(), {"pre_squash_weight": "0", "standing_car_neighbours": "0"}) == TrainConfig()
    for name, value in (("pre_squash_weight", 10.0), ("standing_car_neighbours", 4), ("xi_positions", "step")):
        with pytest.raises(ValueError) as refused:
            TrainConfig.from_json({**paper, name: value})
        message = str(refused.value)
        assert "\n" not in message and message.startswith(f"{name}={value!r}: this experiment was removed")
        assert "docs/tried/training.md#" in message


def _model_file(path: Path, config: TrainConfig, **saved: object) -> Path:
    """A model file (the format of ``crossroads train export``) whose config also holds ``saved``."""
    nets = networks_for(config, "cpu")
    learner = {name: net.state_dict() for name, net in zip(("policy", "value", "adversary"), nets) if net is not None}
    torch.save({"format": FORMAT, "iteration": 0, "config": {**config.to_json(), **saved}, "lineage": [],
                "learner": learner}, path)
    return path


def test_a_model_naming_a_removed_option_loads_only_at_its_neutral_value(tmp_path: Path) -> None:
    small = TrainConfig(hidden_layers=2, hidden_units=32)
    nets, config = load_networks(_model_file(tmp_path / "neutral.pt", small, pre_squash_weight=0.0,
                                             standing_car_neighbours=0, xi_positions="offset"))
    assert config == small and nets.adversary is not None
    with pytest.raises(ValueError, match=r"^standing_car_neighbours=3: this experiment was removed"):
        load_networks(_model_file(tmp_path / "neighbours.pt", small, standing_car_neighbours=3))


def test_the_cli_applies_experiments_in_order_before_set(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[TrainConfig] = []
    monkeypatch.setattr(train_module, "train", lambda config, resume=False: seen.append(config) or tmp_path)
    runner = CliRunner()
    result = runner.invoke(app, ["--out", str(tmp_path), "--experiment", "short-run", "--experiment", "pooled",
                                 "--set", "rule_share=0.4"])
    assert result.exit_code == 0, result.output
    config = seen[-1]
    assert config.experiments == ("short-run", "pooled")
    assert config.participant_encoder == 64 and config.policy_lr == (1e-4, 1e-5) and config.rule_share == 0.4
    assert runner.invoke(app, ["--out", str(tmp_path)]).exit_code == 0
    assert seen[-1] == TrainConfig(out=tmp_path)  # no experiment, no --set: the paper's configuration
    unknown = runner.invoke(app, ["--out", str(tmp_path), "--experiment", "fast"])
    assert unknown.exit_code == 2 and "known: short-run, shipped-apg, pooled" in unknown.output
    removed = runner.invoke(app, ["--out", str(tmp_path), "--set", "pre_squash_weight=1"])
    assert removed.exit_code == 2 and "pre_squash_weight='1': this experiment was removed" in removed.output
    listing = runner.invoke(app, ["experiments"])
    assert listing.exit_code == 0 and all(name in listing.output for name in EXPERIMENTS)
