"""Distillation into another network layout: the fit, the model file and its card, and a run from it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch
from typer.testing import CliRunner

from crossroads.rl.checkpoint import load_networks
from crossroads.rl.cli import app
from crossroads.rl.distill import distill
from crossroads.rl.train import train

from rl.test_train import tiny

POOLED = {"participant_encoder": "8"}


@pytest.fixture(scope="module")
def source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny trained APG run, exported as a model file."""
    tmp = tmp_path_factory.mktemp("source")
    out = tmp / "apg.pt"
    result = CliRunner().invoke(app, ["export", str(train(tiny(tmp, iterations=3, run_name="src"))), "-o", str(out)])
    assert result.exit_code == 0, result.output
    return out


def test_the_fit_reproduces_the_source_and_the_file_starts_a_run(tmp_path: Path, source: Path) -> None:
    unfitted = distill(source, tmp_path / "raw.pt", POOLED, episodes=10, steps=1)
    fitted = distill(source, tmp_path / "fit.pt", POOLED, episodes=10, steps=300, lr=3e-3)
    assert fitted.held_out > 0 and fitted.states > fitted.held_out
    # measured: jerk 2.69 → 0.046 m/s³, value 6.5 % → 0.16 % of the mean value
    assert fitted.jerk_error < 0.5 * unfitted.jerk_error
    assert fitted.value_error < 0.5 * unfitted.value_error

    nets, config = load_networks(tmp_path / "fit.pt")
    src, src_config = load_networks(source)
    assert config.participant_encoder == 8 and nets.policy.encoder is not None
    assert src.adversary is not None and nets.adversary is not None
    assert all(torch.equal(a, b) for a, b in zip(nets.adversary.state_dict().values(),
                                                  src.adversary.state_dict().values(), strict=True))
    card = json.loads((tmp_path / "fit.card.json").read_text())
    assert card["iterations_done"] == 0 and card["iterations_total"] == 3
    assert card["lineage"][-1]["model"] == str(source) and card["distillation"]["steps"] == 300
    assert card["changed_from_defaults"]["participant_encoder"]["run"] == 8

    run = train(tiny(tmp_path, iterations=2, run_name="from-distilled", participant_encoder=8,
                     init_from=tmp_path / "fit.pt"))
    assert (run / "metrics.csv").is_file()
    # flat networks cannot start a pooled run directly: the error says what to do
    with pytest.raises(ValueError, match="distill"):
        train(tiny(tmp_path, iterations=1, run_name="flat-into-pooled", participant_encoder=8, init_from=source))


@pytest.mark.slow
def test_same_seed_same_networks_and_bad_requests_refused(tmp_path: Path, source: Path) -> None:
    distill(source, tmp_path / "a.pt", POOLED, episodes=10, steps=20)
    distill(source, tmp_path / "b.pt", POOLED, episodes=10, steps=20)
    a, b = load_networks(tmp_path / "a.pt")[0], load_networks(tmp_path / "b.pt")[0]
    assert all(torch.equal(x, y) for x, y in zip(a.policy.state_dict().values(), b.policy.state_dict().values(),
                                                  strict=True))
    with pytest.raises(ValueError, match="nothing to distill"):
        distill(source, tmp_path / "c.pt", {"batch_size": "16"}, episodes=10, steps=1)
    with pytest.raises(ValueError, match="episodes"):
        distill(source, tmp_path / "c.pt", POOLED, episodes=3, steps=1)
    result = CliRunner().invoke(app, ["distill", str(source), "-o", str(tmp_path / "d.pt"),
                                      "--set", "participant_encoder=-1"])
    assert result.exit_code != 0 and "participant_encoder" in result.output
