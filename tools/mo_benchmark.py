"""Train one PCHC variant on an MO-Gymnasium task, then measure the Pareto front of the single policy it learned.

    python tools/mo_benchmark.py --task mo-hopper-2obj-v5 --variant pci [--steps 1000000] [--out DIR]

Variants: pci (PCHC's PCI actor), gated (the learned-gate ablation), mlp (a plain MLP on [obs, lambda]); all train
with MultiCriticPPO. The evaluation runs the raw environment (reward scale 1, actions clipped to the action space,
no reward normalisation) with the deterministic mean action at evenly spaced preferences, a fixed set of seeded
episodes each, and sums undiscounted returns. It prints and writes (JSON, PNG) the hypervolume of the non-dominated
points against the stated reference point, their sparsity and count, and training wall time and steps per second.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import os
import time

import numpy as np
import torch

from pchc_rsl.configs import select_actor, task_config
from pchc_rsl.envs.mo_gym import MOGymVecEnv
from pchc_rsl.evaluation import evenly_spaced_preferences
from pchc_rsl.pareto import hypervolume, non_dominated, sparsity

REFERENCE_POINTS = {"mo-hopper-2obj-v5": (-100.0, -100.0), "mo-halfcheetah-v5": (-100.0, -6000.0)}
VARIANTS = ("pci", "gated", "mlp")


def episode_returns(policy, env_cfg, preference, episodes: int, seed: int) -> np.ndarray:
    """[episodes, m] undiscounted raw returns of the first episode of ``episodes`` envs seeded seed, seed+1, ..."""
    env_cfg = copy.deepcopy(env_cfg)
    env_cfg.reward_scale = 1.0
    env = MOGymVecEnv(env_cfg, episodes, "cpu", seed)
    env.set_preference(preference)
    returns = np.zeros((episodes, env.num_objectives))
    running = np.ones(episodes, dtype=bool)
    obs = env.get_observations()
    with torch.inference_mode():
        while running.any():
            obs, _, dones, extras = env.step(policy(obs))
            returns[running] += extras["reward_groups"][:, 1:].numpy()[running]
            running &= ~dones.numpy()
    env.close()
    return returns


def evaluate_front(policy, env_cfg, num_preferences: int, episodes: int, seed: int, reference) -> dict:
    rows = []
    for lam in evenly_spaced_preferences(num_preferences):
        returns = episode_returns(policy, env_cfg, lam, episodes, seed)
        rows.append({"preference": list(lam), "mean_return": returns.mean(0).tolist(),
                     "std_return": returns.std(0).tolist()})
    points = np.array([r["mean_return"] for r in rows])
    front = non_dominated(points)
    return {"rows": rows, "front": front.tolist(), "hypervolume": hypervolume(front, reference),
            "sparsity": sparsity(front), "num_points": int(len(front)), "reference_point": list(reference)}


def plot_front(result: dict, objective_names: list[str], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    points = np.array([r["mean_return"] for r in result["rows"]])
    front = np.array(result["front"])
    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    ax.plot(points[:, 0], points[:, 1], "o", color="0.6", label="all preferences")
    order = np.argsort(front[:, 0])
    ax.plot(front[order, 0], front[order, 1], "o-", label="non-dominated")
    for r, (x, y) in zip(result["rows"], points):
        ax.annotate(f"{r['preference'][0]:.1f}", (x, y), fontsize=7)
    ax.set_xlabel(objective_names[0])
    ax.set_ylabel(objective_names[1])
    ax.set_title(f"{result['task']} {result['variant']}: HV {result['hypervolume']:.4g} "
                 f"(ref {tuple(result['reference_point'])}), S {result['sparsity']:.4g}", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", required=True, choices=sorted(REFERENCE_POINTS))
    parser.add_argument("--variant", required=True, choices=VARIANTS)
    parser.add_argument("--steps", type=int, default=1_000_000, help="env steps to train for")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--num-envs", type=int, help="parallel envs in training (default: the task's)")
    parser.add_argument("--preference-concentration", type=float,
                        help="Dirichlet concentration of the training preferences (default: the task's, 1 = uniform; "
                             "below 1 puts more episodes near the simplex vertices)")
    parser.add_argument("--preferences", type=int, default=11)
    parser.add_argument("--episodes", type=int, default=5, help="evaluation episodes per preference")
    parser.add_argument("--eval-seed", type=int, default=10_000)
    parser.add_argument("--out", help="output folder (default: logs/mo_benchmark/TASK/VARIANT_seedS)")
    args = parser.parse_args(argv)

    from pchc_rsl.cli.common import make_runner

    cfg = task_config(args.task)
    cfg.seed = args.seed
    if args.num_envs is not None:
        cfg.num_envs = args.num_envs
    if args.preference_concentration is not None:
        cfg.env.preference_concentration = args.preference_concentration
    select_actor(cfg.runner.actor, args.variant)
    out = args.out or os.path.join("logs", "mo_benchmark", args.task, f"{args.variant}_seed{args.seed}")
    os.makedirs(out, exist_ok=True)
    steps_per_iteration = cfg.num_envs * cfg.runner.num_steps_per_env
    iterations = max(1, math.ceil(args.steps / steps_per_iteration))

    runner = make_runner(cfg, os.path.join(out, "train"))
    start = time.perf_counter()
    runner.learn(iterations)
    train_time = time.perf_counter() - start
    runner.save(os.path.join(out, "train", "model_final.pt"))
    trained_steps = iterations * steps_per_iteration

    start = time.perf_counter()
    result = evaluate_front(runner.get_inference_policy(), cfg.env, args.preferences, args.episodes,
                            args.eval_seed, REFERENCE_POINTS[args.task])
    result.update(task=args.task, variant=args.variant, seed=args.seed, env_steps=trained_steps,
                  train_wall_time_s=train_time, steps_per_second=trained_steps / train_time,
                  eval_wall_time_s=time.perf_counter() - start, num_episodes=args.episodes)
    with open(os.path.join(out, "result.json"), "w") as f:
        json.dump(result, f, indent=2)
    plot_front(result, cfg.env.objective_names, os.path.join(out, "pareto.png"))
    print(f"{args.task} {args.variant} seed {args.seed}: {trained_steps} steps in {train_time:.0f} s "
          f"({result['steps_per_second']:.0f} steps/s)")
    for row in result["rows"]:
        print(f"  lambda {row['preference'][0]:.1f}/{row['preference'][1]:.1f}: return "
              + ", ".join(f"{v:.1f}" for v in row["mean_return"]))
    print(f"  hypervolume {result['hypervolume']:.6g} (reference point {tuple(result['reference_point'])}), "
          f"sparsity {result['sparsity']:.6g}, {result['num_points']} non-dominated points; {out}")
    return result


if __name__ == "__main__":
    main()
