"""Policy references: the one grammar (rule, sumo, checkpoints, onnx:, py:, +shield) and identities."""

from __future__ import annotations

from pathlib import Path

import pytest

from crossroads.evaluation.sumo_driver import SumoDriverPolicy
from crossroads.policy.ref import PolicyError, PolicyRef, parse_policy
from crossroads.evaluation.policies import load_controller
from crossroads.policy.identity import policy_identity


@pytest.mark.parametrize(("text", "ref", "canonical"), [
    ("rule", PolicyRef("rule"), "rule"),
    ("sumo", PolicyRef("sumo"), "sumo"),
    ("models/apg.pt", PolicyRef("checkpoint", "models/apg.pt"), "models/apg.pt"),
    ("models/apg.pt+shield", PolicyRef("checkpoint", "models/apg.pt", True), "models/apg.pt+shield"),
    ("onnx:out/apg.onnx", PolicyRef("onnx", "out/apg.onnx"), "onnx:out/apg.onnx"),
    ("out/apg.onnx+shield", PolicyRef("onnx", "out/apg.onnx", True), "onnx:out/apg.onnx+shield"),
    ("py:my_pkg.drivers:Careful", PolicyRef("plugin", "my_pkg.drivers:Careful"), "py:my_pkg.drivers:Careful"),
    ("  rule ", PolicyRef("rule"), "rule"),
])
def test_every_form_parses_to_its_typed_reference_and_back(text: str, ref: PolicyRef, canonical: str) -> None:
    assert parse_policy(text) == ref
    assert str(ref) == canonical and parse_policy(canonical) == ref


def test_names_are_short() -> None:
    assert [parse_policy(t).name for t in ("rule", "models/apg.pt+shield", "onnx:x/mine.onnx", "py:a.b:Driver")] == [
        "rule", "apg+shield", "mine", "Driver"]


@pytest.mark.parametrize(("text", "message"), [
    ("", "empty policy reference"),
    ("rule+shield", r"'rule\+shield'.*safety shield.*'rule' has none"),
    ("sumo+shield", r"'sumo\+shield'.*safety shield"),
    ("py:a.b:Driver+shield", r"'py:a.b:Driver\+shield'.*safety shield"),
    ("py:a.b", "py:package.module:Factory"),
    ("py:a..b:X", "py:package.module:Factory"),
    ("py:a.b:not-a-name", "py:package.module:Factory"),
    ("onnx:model.pt", r"onnx:PATH\.onnx.*does not end in \.onnx"),
    ("nothing-like-a-policy", "unknown policy 'nothing-like-a-policy': use one of rule, sumo"),
])
def test_bad_references_say_what_is_wrong(text: str, message: str) -> None:
    with pytest.raises(PolicyError, match=message):
        parse_policy(text)


def test_loading_checks_the_file_and_hands_sumo_to_the_episode_runner(tmp_path: Path) -> None:
    with pytest.raises(PolicyError, match="checkpoint 'nowhere/apg.pt' does not exist"):
        load_controller(parse_policy("nowhere/apg.pt+shield"))
    with pytest.raises(PolicyError, match="ONNX policy 'nowhere/mine.onnx' does not exist"):
        load_controller(parse_policy("onnx:nowhere/mine.onnx"))
    sumo = load_controller(parse_policy("sumo"))
    assert isinstance(sumo, SumoDriverPolicy) and sumo.name == "sumo"
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"not a checkpoint")
    with pytest.raises(PolicyError, match="cannot load the checkpoint"):
        load_controller(parse_policy(str(garbage)))
    assert load_controller(parse_policy("rule")).name == "rule"


def test_a_shielded_checkpoint_is_a_policy_of_its_own_in_the_store(tmp_path: Path) -> None:
    checkpoint = tmp_path / "apg.pt"
    checkpoint.write_bytes(b"weights")
    plain, shielded = policy_identity(str(checkpoint)), policy_identity(f"{checkpoint}+shield")
    assert (plain.name, shielded.name) == ("apg", "apg+shield")
    assert shielded.file_hash == plain.file_hash + "+shield" and shielded.kind == "checkpoint"
    with pytest.raises(PolicyError, match="does not exist"):
        policy_identity(str(tmp_path / "gone.pt+shield"))


def test_onnx_and_plugin_identities(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    model = tmp_path / "mine.onnx"
    model.write_bytes(b"graph bytes")
    ident = policy_identity(str(model))  # a bare .onnx path is an ONNX policy
    assert (ident.kind, ident.name, ident.ref) == ("onnx", "mine", f"onnx:{model}")
    assert ident.file_hash.startswith("sha256:")
    assert policy_identity("sumo").file_hash == "builtin:sumo"
    package = tmp_path / "plugins"
    package.mkdir()
    (package / "drivers_for_identity.py").write_text("class A:\n    pass\n")
    monkeypatch.syspath_prepend(str(package))
    a = policy_identity("py:drivers_for_identity:A")
    b = policy_identity("py:drivers_for_identity:B")  # the same file, another factory: another policy
    assert a.kind == "plugin" and a.name == "A" and a.file_hash != b.file_hash
    (package / "drivers_for_identity.py").write_text("class A:\n    speed = 2\n")
    assert policy_identity("py:drivers_for_identity:A").file_hash != a.file_hash  # edited: a new policy
    with pytest.raises(PolicyError, match="no source file for module 'no_such_module_here'"):
        policy_identity("py:no_such_module_here:X")
