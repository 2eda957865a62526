"""TAR: the total average return of the current policy in real SUMO runs (SPEC §6, paper Fig. 4-5).

TAR = mean over ``tar_runs`` runs of Σ_{t=1..tar_steps} [l(s_t, u_t) + ρ φ(s_{t+1})]. Run r drives on
the r-th (intersection, task) of the config (cycling), world seed ``tar_seed + r`` (the same set at
every evaluation), the ego at its default start (40 m before the stop line, pass-mode speed), the
light as the world config defaults (green). The policy drives as IDC does online: the speed mode by
the light logic, one state per candidate path, τ* = argmin v_w, u = mean action of π_θ on s(τ*).
l uses s_t = that state; φ is the penalty of the safety and road constraints of the next state on
the same path and mode. **(choice)** A run that ends early (collision, off road, passed) sums the
steps it drove; the collision / off-road counts are reported beside TAR.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from crossroads.idc.constraints import penalty, road_constraints, safety_constraints
from crossroads.idc.state import build_states
from crossroads.idc.utility import utility
from crossroads.rl.config import TrainConfig
from crossroads.rl.neural_nets import Networks
from crossroads.idc.observed import observed_others
from crossroads.rl.sampler import net_file, speed_mode
from crossroads.sim.config import WorldConfig
from crossroads.sim.world import World


def evaluate_tar(nets: Networks, config: TrainConfig) -> dict[str, float]:
    """``{"tar", "tar_std", "tar_steps", "tar_collisions", "tar_off_road", "tar_passed"}``."""
    combos = [(n, t) for n in config.intersections for t in config.tasks]
    returns, steps, outcomes = [], [], []
    device = next(nets.policy.parameters()).device
    for r in range(config.tar_runs):
        name, task = combos[r % len(combos)]
        world = World(WorldConfig(net_file=net_file(name), task=task, warmup_s=config.warmup_s))  # type: ignore[arg-type]
        total, n, outcome = 0.0, 0, None
        try:
            obs = world.reset(config.tar_seed + r)
            cands = world.candidates
            for _ in range(config.tar_steps):
                others, _ = observed_others(obs)
                mode = speed_mode(obs)
                states = build_states(obs.ego, others, cands, mode, config.path_preview)
                with torch.no_grad():
                    s = torch.as_tensor(states, dtype=torch.float32, device=device)
                    best = int(torch.argmin(nets.value(s)))
                    u = nets.policy.mean_action(s[best: best + 1])[0].cpu().numpy().astype(np.float64)
                l, _ = utility(states[best], u)
                obs, outcome = world.step(u)
                nxt_others, _ = observed_others(obs)
                nxt = build_states(obs.ego, nxt_others, [cands[best]], mode)[0]
                phi = penalty(np.concatenate([safety_constraints(nxt), road_constraints(nxt)]))
                total += float(l) + config.rho * float(phi)
                n += 1
                if outcome is not None:
                    break
        finally:
            world.close()
        returns.append(total)
        steps.append(n)
        outcomes.append(outcome.kind if outcome is not None else "running")
    out: dict[str, Any] = {
        "tar": float(np.mean(returns)), "tar_std": float(np.std(returns)), "tar_steps": float(np.mean(steps)),
        "tar_collisions": float(sum(o == "collision" for o in outcomes)),
        "tar_off_road": float(sum(o == "off_road" for o in outcomes)),
        "tar_passed": float(sum(o == "passed" for o in outcomes)),
    }
    return out
