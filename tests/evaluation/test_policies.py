"""Policy references: built-in names, checkpoint paths and the safety shield's suffix."""

from __future__ import annotations

from pathlib import Path

import pytest

from crossroads.evaluation.policies import PolicyError, load_controller, split_shield
from crossroads.store.crud import policy_identity


def test_the_shield_suffix_is_split_off() -> None:
    assert split_shield("models/apg.pt+shield") == ("models/apg.pt", True)
    assert split_shield("models/apg.pt") == ("models/apg.pt", False)
    assert split_shield("rule") == ("rule", False)


def test_the_rule_controller_has_no_plan_to_shield() -> None:
    with pytest.raises(PolicyError, match=r"'rule\+shield'.*safety shield.*'rule' has none"):
        load_controller("rule+shield")
    with pytest.raises(PolicyError, match="does not exist"):
        load_controller("nowhere/apg.pt+shield")


def test_a_shielded_checkpoint_is_a_policy_of_its_own_in_the_store(tmp_path: Path) -> None:
    checkpoint = tmp_path / "apg.pt"
    checkpoint.write_bytes(b"weights")
    plain, shielded = policy_identity(str(checkpoint)), policy_identity(f"{checkpoint}+shield")
    assert (plain.name, shielded.name) == ("apg", "apg+shield")
    assert shielded.file_hash == plain.file_hash + "+shield" and shielded.kind == "checkpoint"
    with pytest.raises(PolicyError, match="does not exist"):
        policy_identity(str(tmp_path / "gone.pt+shield"))
