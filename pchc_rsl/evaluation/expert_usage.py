"""Which experts a mixture actor (PCI or gated) uses at each preference, over the states its own policy visits.

Why: an expert trains on the samples in proportion to its routing weight. PCI's routing is fixed by lambda, so the
preferences partition the data among the experts; the gated ablation learns its gate, and this shows whether it
partitions them too or shares experts across preferences.
"""

from __future__ import annotations

import numpy as np
import torch
from torch.distributions import Categorical

from pchc_rsl.evaluation.checkpoint import loaded_policy
from pchc_rsl.evaluation.presets import evenly_spaced_preferences
from pchc_rsl.runners.checkpoint import load_checkpoint
from pchc_rsl.training.build import restore_config, saved_config


def mean_routing(runner, preference, steps: int) -> tuple[np.ndarray, float]:
    """[E] routing weights averaged over ``steps`` policy steps of every env at a fixed preference, and the mean
    entropy of the weights state by state (a gate can route sharply by state yet evenly on average)."""
    head = runner.alg.actor.mlp
    if not hasattr(head, "routing"):
        raise ValueError(f"The actor's head is a {type(head).__name__}, not a mixture of experts (PCI or gated).")
    seen, entropies = [], []

    def record(module, args):
        weights = module.routing(args[0])
        seen.append(weights.mean(0))
        entropies.append(Categorical(probs=weights).entropy().mean())

    hook = head.register_forward_pre_hook(record)
    env, policy = runner.env, runner.get_inference_policy()
    env.set_preference(preference)
    obs = env.get_observations()
    try:
        with torch.inference_mode():
            for _ in range(steps):
                obs, *_ = env.step(policy(obs))
    finally:
        hook.remove()
    return torch.stack(seen).mean(0).cpu().numpy(), torch.stack(entropies).mean().item()


def expert_usage(checkpoint: str, preferences: int = 11, steps: int = 200, num_envs: int = 8, seed: int = 0) -> dict:
    """preferences [P, 2], weights [P, E] (mean routing weights), entropy [P] (of those), per_state_entropy [P]."""
    cfg = restore_config(saved_config(checkpoint, load_checkpoint(checkpoint)))
    if len(cfg.env.objective_names) != 2:
        raise ValueError("expert usage walks the preferences from (1, 0) to (0, 1): two objectives only.")
    cfg.num_envs, cfg.seed, cfg.device, cfg.fixed_preference = num_envs, seed, "cpu", None
    runner, _ = loaded_policy(checkpoint, cfg)
    lams = evenly_spaced_preferences(preferences)
    routed = [mean_routing(runner, lam, steps) for lam in lams]
    weights = np.stack([w for w, _ in routed])
    return {"preferences": np.array(lams), "weights": weights,
            "entropy": Categorical(probs=torch.as_tensor(weights)).entropy().numpy(),
            "per_state_entropy": np.array([e for _, e in routed])}
