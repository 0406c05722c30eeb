"""Train one PCHC variant on an MO-Gymnasium task, then measure the Pareto front of the single policy it learned.

    python tools/mo_benchmark.py --task mo-hopper-2obj-v5 --variant pci [--steps 1000000] [--out DIR]

Variants (all trained with MultiCriticPPO): pci (PCHC's PCI actor, experts see lambda: the paper's design),
pci-blind (PCI with preference-blind experts: lambda acts only through the routing), gated (the learned-gate
"w/o PCI" ablation, experts see lambda), mlp (a plain MLP on [obs, lambda]). ``--fixed-preference`` trains one
fixed weighting instead (claim (d)'s per-preference policies) and evaluates it at that preference only.
The evaluation runs the raw environment (actions clipped to the action space) with the deterministic mean action
at evenly spaced preferences (two objectives) or on a simplex lattice (three or more), a fixed set of seeded
episodes each, and sums undiscounted returns. It prints and writes (JSON, PNG) the hypervolume of the non-dominated
points against the task's reference point, their sparsity and count, the hypervolume after every ``--eval-every``
env steps, and training wall time and steps per second.
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
from pchc_rsl.preference import simplex_lattice, validate_preference

REFERENCE_POINTS = {
    # Below every return a policy that moves at all reaches in 1000 steps; energy objectives: -sum a^2 per step
    # (6 actuators in [-1, 1] for halfcheetah and walker2d, 3 for hopper) plus the healthy reward where the env
    # adds it to every objective (walker2d, hopper).
    "mo-hopper-2obj-v5": (-100.0, -100.0),
    "mo-halfcheetah-v5": (-100.0, -6000.0),
    "mo-walker2d-v5": (-100.0, -5000.0),
    "mo-hopper-v5": (-100.0, -100.0, -2000.0),
}
VARIANTS = {
    "pci": ("pci", {}),
    "pci-blind": ("pci", {"experts_see_preference": False}),
    "gated": ("gated", {}),
    "mlp": ("mlp", {}),
}


def evaluation_preferences(num_objectives: int, count: int, lattice_resolution: int) -> list[tuple[float, ...]]:
    """Two objectives: ``count`` evenly spaced from (1, 0) to (0, 1); more: every point of the simplex lattice."""
    if num_objectives == 2:
        return evenly_spaced_preferences(count)
    return [tuple(p) for p in simplex_lattice(num_objectives, lattice_resolution).tolist()]


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


def evaluate_front(policy, env_cfg, preferences, episodes: int, seed: int, reference) -> dict:
    rows = []
    for lam in preferences:
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
    if points.shape[1] == 2:
        ax.plot(points[:, 0], points[:, 1], "o", color="0.6", label="all preferences")
        order = np.argsort(front[:, 0])
        ax.plot(front[order, 0], front[order, 1], "o-", label="non-dominated")
        for r, (x, y) in zip(result["rows"], points):
            ax.annotate(f"{r['preference'][0]:.2f}", (x, y), fontsize=7)
    else:  # the first two objectives, the third as colour
        scatter = ax.scatter(points[:, 0], points[:, 1], c=points[:, 2], cmap="viridis", label="all preferences")
        fig.colorbar(scatter, ax=ax, label=objective_names[2])
    ax.set_xlabel(objective_names[0])
    ax.set_ylabel(objective_names[1])
    ax.set_title(f"{result['task']} {result['variant']}: HV {result['hypervolume']:.4g} "
                 f"(ref {tuple(result['reference_point'])}), S {result['sparsity']:.4g}", fontsize=8)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", required=True, choices=sorted(REFERENCE_POINTS))
    parser.add_argument("--variant", required=True, choices=sorted(VARIANTS))
    parser.add_argument("--steps", type=int, default=1_000_000, help="env steps to train for")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--num-envs", type=int, help="parallel envs in training (default: the task's)")
    parser.add_argument("--preference-concentration", type=float,
                        help="Dirichlet concentration of the training preferences (default: the task's, 1 = uniform; "
                             "below 1 puts more episodes near the simplex vertices)")
    parser.add_argument("--routing-scale", type=float, help="PCI routing scale s (default: the actor's)")
    parser.add_argument("--fixed-preference", metavar="L1,L2,...",
                        help="train at this preference only and evaluate there (one point of the front)")
    parser.add_argument("--preferences", type=int, default=11, help="evaluation preferences (two objectives)")
    parser.add_argument("--lattice-resolution", type=int, default=6,
                        help="evaluation lattice resolution for three or more objectives (6: 28 points for three)")
    parser.add_argument("--episodes", type=int, default=5, help="evaluation episodes per preference")
    parser.add_argument("--eval-every", type=int, default=250_000,
                        help="also evaluate the front after every this many env steps (0: only at the end)")
    parser.add_argument("--eval-seed", type=int, default=10_000)
    parser.add_argument("--out", help="output folder (default: logs/mo_benchmark/TASK/VARIANT_seedS)")
    return parser


def main(argv: list[str] | None = None) -> dict:
    args = build_parser().parse_args(argv)
    from pchc_rsl.build import make_runner

    cfg = task_config(args.task)
    cfg.seed = args.seed
    if args.num_envs is not None:
        cfg.num_envs = args.num_envs
    if args.preference_concentration is not None:
        cfg.env.preference_concentration = args.preference_concentration
    actor_variant, actor_kwargs = VARIANTS[args.variant]
    select_actor(cfg.runner.actor, actor_variant)
    cfg.runner.actor.kwargs.update(actor_kwargs)
    if args.routing_scale is not None:
        if actor_variant != "pci":
            raise SystemExit(f"--routing-scale applies to the PCI actor, not to variant '{args.variant}'.")
        cfg.runner.actor.kwargs["routing_scale"] = args.routing_scale
    num_objectives = len(cfg.env.objective_names)
    if args.fixed_preference is not None:
        lam = validate_preference([float(x) for x in args.fixed_preference.split(",")], num_objectives)
        cfg.fixed_preference = lam.tolist()
        preferences = [tuple(cfg.fixed_preference)]
    else:
        preferences = evaluation_preferences(num_objectives, args.preferences, args.lattice_resolution)
    out = args.out or os.path.join("logs", "mo_benchmark", args.task, f"{args.variant}_seed{args.seed}")
    os.makedirs(out, exist_ok=True)
    steps_per_iteration = cfg.num_envs * cfg.runner.num_steps_per_env
    iterations = max(1, math.ceil(args.steps / steps_per_iteration))
    chunk = iterations if args.eval_every <= 0 else max(1, args.eval_every // steps_per_iteration)

    def evaluate(policy) -> dict:
        return evaluate_front(policy, cfg.env, preferences, args.episodes, args.eval_seed,
                              REFERENCE_POINTS[args.task])

    runner = make_runner(cfg, os.path.join(out, "train"))
    train_time, done, history = 0.0, 0, []
    while done < iterations:
        step = min(chunk, iterations - done)
        start = time.perf_counter()
        runner.learn(step)
        train_time += time.perf_counter() - start
        done += step
        if done < iterations:
            partial = evaluate(runner.get_inference_policy())
            history.append({"env_steps": done * steps_per_iteration, "hypervolume": partial["hypervolume"]})
    runner.save(os.path.join(out, "train", "model_final.pt"))
    trained_steps = iterations * steps_per_iteration

    start = time.perf_counter()
    result = evaluate(runner.get_inference_policy())
    history.append({"env_steps": trained_steps, "hypervolume": result["hypervolume"]})
    result.update(task=args.task, variant=args.variant, seed=args.seed, env_steps=trained_steps,
                  train_wall_time_s=train_time, steps_per_second=trained_steps / train_time,
                  eval_wall_time_s=time.perf_counter() - start, num_episodes=args.episodes, history=history,
                  fixed_preference=cfg.fixed_preference, routing_scale=cfg.runner.actor.kwargs.get("routing_scale"),
                  preference_concentration=cfg.env.preference_concentration)
    with open(os.path.join(out, "result.json"), "w") as f:
        json.dump(result, f, indent=2)
    plot_front(result, cfg.env.objective_names, os.path.join(out, "pareto.png"))
    print(f"{args.task} {args.variant} seed {args.seed}: {trained_steps} steps in {train_time:.0f} s "
          f"({result['steps_per_second']:.0f} steps/s)")
    for row in result["rows"]:
        print("  lambda " + "/".join(f"{v:.2f}" for v in row["preference"]) + ": return "
              + ", ".join(f"{v:.1f}" for v in row["mean_return"]))
    print(f"  hypervolume {result['hypervolume']:.6g} (reference point {tuple(result['reference_point'])}), "
          f"sparsity {result['sparsity']:.6g}, {result['num_points']} non-dominated points; {out}")
    return result


if __name__ == "__main__":
    main()
