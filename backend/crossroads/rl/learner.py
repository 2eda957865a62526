"""The optimisation of Algorithm 1: value step, policy step, adversary step (SPEC §6).

One iteration k on a batch of initial states:

1. roll the batch out through the model (u ~ π_θ, ξ ~ π_φ for APG, ξ ≡ 0 for DPG) → J_track, J_safe;
2. value step: J_v = mean (v_w(s_0, τ) − J_track)², J_track detached (the regression target);
   w ← w − β_w ∇_w J_v;
3. policy step: J_π = mean (J_track + ρ J_safe); θ ← θ − β_θ ∂_θ J_π (or the driving policy's own
   variant, ``TrainConfig.policy_loss``; see ``Learner.policy_loss``);
4. adversary step, when k % m == 0 (APG only): φ ← φ + β_φ ∂_φ J_π (gradient ASCENT: Adam with
   ``maximize=True``), on the same J_π of step 1 (Algorithm 1 computes J_π once per iteration).

Each network has its own Adam and cosine-annealing schedule (stepped once per iteration, for the
adversary too). Gradients are taken with ``torch.autograd.grad`` for exactly the parameters of the
network being stepped, so a step can only move its own network.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from torch import Tensor, nn

from crossroads.rl.buffer import StateBatch
from crossroads.rl.config import TrainConfig
from crossroads.rl.idc_model import IDCModel, Rollout, policy_fns
from crossroads.rl.neural_nets import Networks, networks_for


@dataclass
class Losses:
    """The scalars of one iteration (plain floats)."""

    j_v: float
    j_track: float
    j_safe: float
    j_pi: float
    saturated_share: float = 0.0
    """Share of the driving policy's pre-tanh outputs over the rollout with |z| > ``pre_squash_bound``."""
    j_safe_per_state: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32), repr=False)
    """J_safe of each state of the batch (the buffer's danger scores, see ``ReplayBuffer``)."""


class Learner:
    """Networks, their optimisers and schedulers, and the update of Algorithm 1."""

    def __init__(self, config: TrainConfig, model: IDCModel, device: str | torch.device = "cpu") -> None:
        self.config = config
        self.model = model
        self.device = torch.device(device)
        self.nets: Networks = networks_for(config, self.device)
        betas = config.adam_betas

        def adam(module: nn.Module, lr: tuple[float, float], maximize: bool = False) -> tuple[Any, Any]:
            opt = torch.optim.Adam(module.parameters(), lr=lr[0], betas=betas, maximize=maximize)
            sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=config.iterations, eta_min=lr[1])
            return opt, sched

        self.policy_opt, self.policy_sched = adam(self.nets.policy, config.policy_lr)
        self.value_opt, self.value_sched = adam(self.nets.value, config.value_lr)
        self.adversary_opt = self.adversary_sched = None
        if self.nets.adversary is not None:
            self.adversary_opt, self.adversary_sched = adam(self.nets.adversary, config.adversary_lr, maximize=True)

    # --- losses ------------------------------------------------------------------------------------

    def rollout(self, batch: StateBatch, sample: bool | None = None,
                pre_squash: list[Tensor] | None = None) -> Rollout:
        sample = self.config.sample_actions if sample is None else sample
        act, disturb = policy_fns(self.nets.policy, self.nets.adversary, sample, pre_squash)
        return self.model.rollout(batch, act, disturb, self.config.horizon)

    def losses(self, batch: StateBatch, sample: bool | None = None,
               pre_squash: list[Tensor] | None = None) -> tuple[Tensor, Tensor, Rollout]:
        """(J_v, J_π, rollout) of a batch, as graphs (``pre_squash``: see ``model.policy_fns``)."""
        out = self.rollout(batch, sample, pre_squash)
        v = self.nets.value(out.s0)
        j_v = torch.mean((v - out.j_track.detach()) ** 2)
        j_pi = torch.mean(out.j_track + self.config.rho * out.j_safe)
        return j_v, j_pi, out

    def policy_loss(self, out: Rollout, j_pi: Tensor) -> Tensor:
        """What the driving policy's step minimises (``TrainConfig.policy_loss``); ``j_pi`` itself
        under the paper's "mean"."""
        per_state = out.j_track + self.config.rho * out.j_safe
        if self.config.policy_loss == "log":
            return torch.mean(torch.log1p(per_state))
        if self.config.policy_loss == "sqrt":
            return torch.mean(2.0 * torch.sqrt(1.0 + per_state))
        return j_pi

    # --- the update ----------------------------------------------------------------------------------

    def adversary_due(self, iteration: int) -> bool:
        return self.nets.adversary is not None and iteration % self.config.adversary_interval == 0

    def _apply(self, module: nn.Module, opt: torch.optim.Optimizer, grads: tuple[Tensor | None, ...]) -> None:
        params = list(module.parameters())
        for p, g in zip(params, grads):
            p.grad = None if g is None else g.detach()
        if self.config.max_grad_norm is not None:
            nn.utils.clip_grad_norm_(params, self.config.max_grad_norm)
        opt.step()
        opt.zero_grad(set_to_none=True)

    def update(self, batch: StateBatch, iteration: int, *, value: bool = True, policy: bool = True,
               adversary: bool | None = None, step_schedulers: bool = True) -> Losses:
        """One iteration of Algorithm 1 on ``batch``. ``adversary=None``: by k % m (module docstring).

        The flags let tests take a single step of one network.
        """
        adversary = self.adversary_due(iteration) if adversary is None else adversary
        adversary = adversary and self.nets.adversary is not None
        pre_squash: list[Tensor] = []
        j_v, j_pi, out = self.losses(batch, pre_squash=pre_squash)
        z = torch.stack(pre_squash).detach()  # [T, B, 2] the driving policy's pre-tanh means
        if value:
            w = list(self.nets.value.parameters())
            self._apply(self.nets.value, self.value_opt, torch.autograd.grad(j_v, w, allow_unused=True))
        theta = list(self.nets.policy.parameters()) if policy else []
        phi = list(self.nets.adversary.parameters()) if adversary else []  # type: ignore[union-attr]
        if theta or phi:
            policy_loss = self.policy_loss(out, j_pi)
            if theta and policy_loss is not j_pi:  # the policy's own loss; the adversary keeps J_π
                grads = torch.autograd.grad(policy_loss, theta, allow_unused=True, retain_graph=bool(phi))
                if phi:
                    grads += torch.autograd.grad(j_pi, phi, allow_unused=True)
            else:
                grads = torch.autograd.grad(j_pi, theta + phi, allow_unused=True)
            if theta:
                self._apply(self.nets.policy, self.policy_opt, grads[: len(theta)])
            if phi:
                assert self.adversary_opt is not None
                self._apply(self.nets.adversary, self.adversary_opt, grads[len(theta):])  # type: ignore[arg-type]
        if step_schedulers:
            with warnings.catch_warnings():  # the adversary's schedule runs on while it is not stepped
                warnings.filterwarnings("ignore", message="Detected call of `lr_scheduler.step", category=UserWarning)
                for sched in (self.value_sched, self.policy_sched, self.adversary_sched):
                    if sched is not None:
                        sched.step()
        j_safe = out.j_safe.detach()
        saturated = (z.abs() > self.config.pre_squash_bound).float().mean()
        return Losses(float(j_v.detach()), float(out.j_track.detach().mean()), float(j_safe.mean()),
                      float(j_pi.detach()), float(saturated), j_safe.cpu().numpy().astype(np.float32))

    def danger(self, batch: StateBatch) -> np.ndarray:
        """J_safe of the current policy's plan (means, no gradient) from each state of ``batch``:
        how the buffer scores new states before they are drawn."""
        with torch.no_grad():
            return self.rollout(batch, sample=False).j_safe.cpu().numpy().astype(np.float32)

    # --- state ---------------------------------------------------------------------------------------

    def lrs(self) -> dict[str, float]:
        out = {"policy": self.policy_opt.param_groups[0]["lr"], "value": self.value_opt.param_groups[0]["lr"]}
        if self.adversary_opt is not None:
            out["adversary"] = self.adversary_opt.param_groups[0]["lr"]
        return out

    def state_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "policy": self.nets.policy.state_dict(), "value": self.nets.value.state_dict(),
            "policy_opt": self.policy_opt.state_dict(), "value_opt": self.value_opt.state_dict(),
            "policy_sched": self.policy_sched.state_dict(), "value_sched": self.value_sched.state_dict(),
        }
        if self.nets.adversary is not None:
            assert self.adversary_opt is not None and self.adversary_sched is not None
            out.update(adversary=self.nets.adversary.state_dict(), adversary_opt=self.adversary_opt.state_dict(),
                       adversary_sched=self.adversary_sched.state_dict())
        return out

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.nets.policy.load_state_dict(state["policy"])
        self.nets.value.load_state_dict(state["value"])
        self.policy_opt.load_state_dict(state["policy_opt"])
        self.value_opt.load_state_dict(state["value_opt"])
        self.policy_sched.load_state_dict(state["policy_sched"])
        self.value_sched.load_state_dict(state["value_sched"])
        if self.nets.adversary is not None:
            assert self.adversary_opt is not None and self.adversary_sched is not None
            self.nets.adversary.load_state_dict(state["adversary"])
            self.adversary_opt.load_state_dict(state["adversary_opt"])
            self.adversary_sched.load_state_dict(state["adversary_sched"])
