"""Which experts a mixture actor (PCI or gated) uses at each preference, over the states its own policy visits.

    python tools/expert_usage.py RUN/model_final.pt [--preferences 11] [--steps 200] [--num-envs 8]

Why: an expert trains on the samples in proportion to its routing weight. PCI's routing is fixed by lambda, so
the preferences partition the data among the experts; the gated ablation learns its gate, and this shows whether
it partitions them too or shares experts across preferences. Prints, per preference, each expert's mean weight,
the entropy of those mean weights and the mean entropy state by state (nats; log E when even), then each expert's
share of all the routing weight over the preferences (what it trains on when lambda is sampled evenly).
"""

from __future__ import annotations

import argparse

import numpy as np
import torch
from torch.distributions import Categorical

from pchc_rsl.evaluation import loaded_policy
from pchc_rsl.evaluation import evenly_spaced_preferences
from pchc_rsl.runners.checkpoint import load_checkpoint
from pchc_rsl.training.build import restore_config, saved_config


def mean_routing(runner, preference, steps: int) -> tuple[np.ndarray, float]:
    """[E] routing weights averaged over ``steps`` policy steps of every env at a fixed preference, and the mean
    entropy of the weights state by state (a gate can route sharply by state yet evenly on average)."""
    head = runner.alg.actor.mlp
    if not hasattr(head, "routing"):
        raise SystemExit(f"The actor's head is a {type(head).__name__}, not a mixture of experts (PCI or gated).")
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
        raise SystemExit("expert_usage walks the preferences from (1, 0) to (0, 1): two objectives only.")
    cfg.num_envs, cfg.seed, cfg.device, cfg.fixed_preference = num_envs, seed, "cpu", None
    runner, _ = loaded_policy(checkpoint, cfg)
    lams = evenly_spaced_preferences(preferences)
    routed = [mean_routing(runner, lam, steps) for lam in lams]
    weights = np.stack([w for w, _ in routed])
    return {"preferences": np.array(lams), "weights": weights,
            "entropy": Categorical(probs=torch.as_tensor(weights)).entropy().numpy(),
            "per_state_entropy": np.array([e for _, e in routed])}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("checkpoint")
    parser.add_argument("--preferences", type=int, default=11, help="evenly spaced from (1, 0) to (0, 1)")
    parser.add_argument("--steps", type=int, default=200, help="policy steps per preference")
    parser.add_argument("--num-envs", type=int, default=8)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    usage = expert_usage(args.checkpoint, args.preferences, args.steps, args.num_envs, args.seed)
    experts = usage["weights"].shape[1]
    print(f"{args.checkpoint}: mean routing weight of each expert, {args.num_envs} envs x {args.steps} steps each; "
          f"entropy of the mean weights and mean entropy per state (nats, even: {np.log(experts):.3f})")
    print("preference     " + " ".join(f"  e{j}  " for j in range(experts)) + "  entropy  per state")
    for lam, w, e, per_state in zip(*(usage[k] for k in ("preferences", "weights", "entropy", "per_state_entropy"))):
        print(f"({lam[0]:.2f}, {lam[1]:.2f})  " + " ".join(f"{x:6.3f}" for x in w) + f"  {e:7.3f}  {per_state:9.3f}")
    print("share          " + " ".join(f"{x:6.3f}" for x in usage["weights"].mean(0)))
    return usage


if __name__ == "__main__":
    main()
