"""Train one PCHC variant on an MO-Gymnasium task, then measure the Pareto front of the single policy it learned.

    python tools/studies/mo_benchmark.py --task mo-hopper-2obj-v5 --variant pci [--steps 1000000] [--out DIR]

Variants (all trained with MultiCriticPPO): pci (PCHC's PCI actor, experts see lambda: the paper's design),
pci-blind (PCI with preference-blind experts: lambda acts only through the routing), gated (the learned-gate
"w/o PCI" ablation, experts see lambda), mlp (a plain MLP on [obs, lambda]). ``--fixed-preference`` trains one
fixed weighting instead (claim (d)'s per-preference policies) and evaluates it at that preference only.
The evaluation runs the raw environment (actions clipped to the action space) with the deterministic mean action
at evenly spaced preferences (two objectives) or on a simplex lattice (three or more), a fixed set of seeded
episodes each, and sums undiscounted returns. It prints and writes (JSON, PNG) the hypervolume of the non-dominated
points against the task's reference point, their sparsity and count, the expected utility (the mean over the
preferences of lambda . returns normalised by the task's OBJECTIVE_RANGES), and training wall time and steps per
second. Evaluations sit on a fixed grid: after the first update at or past every multiple of ``--eval-every`` env
steps, and at the end of training, each keeping its per-preference returns, so runs of any length share evaluation
points. ``--match-pci-parameters`` gives the gated variant PCI's expert count and parameter count
(configs/matched_gate.py). Each rollout's routing mass per expert (mixture actors) is read back from the training log.
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
from pchc_rsl.configs.matched_gate import matched_gate, matched_pci_variant
from pchc_rsl.configs.mo_gym import OBJECTIVE_RANGES, REFERENCE_POINTS
from pchc_rsl.envs.mo_gym import MOGymVecEnv
from pchc_rsl.evaluation import evenly_spaced_preferences
from pchc_rsl.pareto import expected_utility, hypervolume, non_dominated, sparsity
from pchc_rsl.preference import simplex_lattice, validate_preference
from pchc_rsl.training.build import make_runner
from pchc_rsl.training.study_cells import run_checkpoints, train_folders
from pchc_rsl.utils.files import write_json

VARIANTS = {
    "pci": ("pci", {}),
    "pci-blind": ("pci", {"experts_see_preference": False}),
    "pci-residual": ("pci", {"residual_experts": True}),
    "pci-warmup": ("pci", {}),  # routing_warmup_updates: the first quarter of the run's updates (main)
    "pci-prior-gate": ("pci", {"prior_gate_hidden_dims": [64]}),
    "pci-floor": ("pci", {"routing_floor": 0.05}),
    "gated": ("gated", {}),
    "mlp": ("mlp", {}),
}
"""Variants: the actor and its kwargs. The pci-* options keep PCI's lambda-routed experts and change what they share
(pchc_rsl/modules/pci.py, PCIHead): residual experts on a shared network, the routing scale warmed up from 0 over the
first quarter of training, a learned gate on the Beta density (its hidden width the gate's), a floor of 0.05 on every
expert's weight."""
SIZED_LIKE_PCI = ("gated", "pci-residual", "pci-prior-gate")
"""The variants that add networks to PCI's experts, which --match-pci-parameters sizes like the PCI actor."""


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


def with_expected_utility(result: dict, objective_range) -> dict:
    """Add the expected utility of an evaluate_front result and the range it was normalised by."""
    low, high = objective_range
    result["expected_utility"] = expected_utility([r["mean_return"] for r in result["rows"]],
                                                  [r["preference"] for r in result["rows"]], low, high)
    result["objective_range"] = {"low": list(low), "high": list(high)}
    return result


def evaluation_iterations(total_iterations: int, steps_per_iteration: int, eval_every: int) -> list[int]:
    """Iterations after which to evaluate: the first at or past each multiple of ``eval_every`` env steps, and the last.

    The grid is in env steps, not in chunks of iterations, so the evaluations land at the same points whatever the
    run's length, and the final one is never a separate evaluation one update after the last grid point.
    """
    if eval_every <= 0:
        return [total_iterations]
    marks = set()
    k = 1
    while (it := math.ceil(k * eval_every / steps_per_iteration)) < total_iterations:
        marks.add(it)
        k += 1
    return sorted(marks | {total_iterations})


def history_entry(result: dict, env_steps: int) -> dict:
    """One evaluation of a run: its env steps, measures and per-preference mean returns."""
    return {"env_steps": env_steps, "hypervolume": result["hypervolume"],
            "expected_utility": result["expected_utility"], "num_points": result["num_points"],
            "mean_returns": [r["mean_return"] for r in result["rows"]]}


def routing_mass_per_rollout(out: str) -> dict | None:
    """{"iterations": [...], "per_expert": [[mass of expert j at each iteration] for j]} from the run's TensorBoard
    logs (MultiCriticPPO logs it for mixture actors); an iteration a resumed run trained again counts as last
    trained. None when the logs hold no routing mass."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    latest: dict[str, dict[int, float]] = {}
    for folder in train_folders(out):
        if not os.path.isdir(folder):
            continue
        events = EventAccumulator(folder, size_guidance={"scalars": 0})
        events.Reload()
        for tag in (t for t in events.Tags().get("scalars", []) if t.startswith("Routing/expert_")):
            latest.setdefault(tag, {}).update({e.step: e.value for e in events.Scalars(tag)})
    if not latest:
        return None
    tags = sorted(latest, key=lambda t: int(t.rsplit("_", 1)[1]))
    iterations = sorted(latest[tags[0]])
    return {"iterations": iterations, "per_expert": [[latest[t][i] for i in iterations] for t in tags]}


def matched_actor(cfg, variant: str):
    """The variant's actor config sized like this task's PCI actor, and both parameter counts."""
    env = MOGymVecEnv(cfg.env, 1, "cpu", 0)
    obs = env.get_observations()
    env.close()
    pci = copy.deepcopy(task_config(cfg.name).runner.actor)
    select_actor(pci, "pci")
    groups = {"actor": cfg.runner.obs_groups["actor"]}
    if variant == "gated":
        return matched_gate(pci, obs, groups, env.num_actions)
    return matched_pci_variant(pci, cfg.runner.actor, obs, groups, env.num_actions)


def resume(runner, saved: dict[int, str], progress_path: str, grid: list[int], steps_per_iteration: int, evaluate,
           fresh: dict) -> dict:
    """Continue an interrupted run from its newest checkpoint (model_<it>.pt, which rsl-rl writes after every
    evaluation chunk and every save_interval iterations), with its random streams.

    The evaluations already done come from progress.json; any missing (a run started without it) are redone from the
    checkpoint at that grid point, which gives the same numbers (deterministic policy, seeded episodes). The
    environments start new episodes, so a resumed run matches an uninterrupted one in distribution, not bit for bit.
    Its wall and CPU times cover the sessions that wrote progress.json (``cpu_seconds_complete`` says whether that
    is all of them).
    """
    progress = fresh
    if os.path.isfile(progress_path):
        with open(progress_path) as f:
            progress = json.load(f)
    if not saved:
        return progress
    newest = max(saved)
    done = min(newest + 1, grid[-1])
    history = {h["env_steps"]: h for h in progress["history"] if h["env_steps"] <= done * steps_per_iteration}
    for g in (g for g in grid if g <= done and g * steps_per_iteration not in history):
        if g - 1 not in saved:
            raise SystemExit(f"Cannot resume: the evaluation after iteration {g - 1} is not in {progress_path} and "
                             f"model_{g - 1}.pt is missing; start the run afresh.")
        runner.load(saved[g - 1])
        result = evaluate(runner.get_inference_policy())
        history[g * steps_per_iteration] = history_entry(result, g * steps_per_iteration)
        progress["last_result"] = result
        progress["cpu_seconds_complete"] = False  # the interrupted session's time is not known
    runner.load(saved[newest], resume=True)
    progress["history"] = [history[k] for k in sorted(history)]
    progress["done"] = done
    progress["resumed"] += 1
    print(f"resuming {saved[newest]} (after iteration {newest}): {len(history)} evaluations kept or redone",
          flush=True)
    return progress


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
    parser.add_argument("--match-pci-parameters", action="store_true",
                        help=f"{', '.join(SIZED_LIKE_PCI)}: expert widths that make the parameter count PCI's on this "
                             "task (the gate also gets PCI's expert count; configs/matched_gate.py)")
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
    parser.add_argument("--resume", action="store_true",
                        help="continue an interrupted run in --out from its newest checkpoint (a finished one is left "
                             "as it is; an empty folder starts afresh)")
    return parser


def main(argv: list[str] | None = None) -> dict:
    args = build_parser().parse_args(argv)
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
    parameters = None
    if args.match_pci_parameters:
        if args.variant not in SIZED_LIKE_PCI:
            raise SystemExit(f"--match-pci-parameters sizes the variants {', '.join(SIZED_LIKE_PCI)}, not "
                             f"'{args.variant}' (it has PCI's parameters).")
        cfg.runner.actor, parameters = matched_actor(cfg, args.variant)
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
    if args.variant == "pci-warmup":
        cfg.runner.actor.kwargs["routing_warmup_updates"] = max(1, iterations // 4)

    def evaluate(policy) -> dict:
        result = evaluate_front(policy, cfg.env, preferences, args.episodes, args.eval_seed, REFERENCE_POINTS[args.task])
        return with_expected_utility(result, OBJECTIVE_RANGES[args.task])

    if args.resume and os.path.isfile(os.path.join(out, "result.json")):
        print(f"{out} is finished (result.json); nothing to resume")
        with open(os.path.join(out, "result.json")) as f:
            return json.load(f)
    saved = run_checkpoints(out) if args.resume else {}
    train_dir = os.path.join(out, f"train_resumed{len(train_folders(out))}" if saved else "train")
    runner = make_runner(cfg, train_dir)
    if parameters is None:
        parameters = {"actor": sum(p.numel() for p in runner.alg.actor.parameters())}
    grid = evaluation_iterations(iterations, steps_per_iteration, args.eval_every)
    cpu_start = time.process_time()
    progress = {"done": 0, "history": [], "last_result": None, "train_wall_time_s": 0.0, "eval_wall_time_s": 0.0,
                "cpu_seconds": 0.0, "cpu_seconds_complete": True, "resumed": 0}
    if args.resume:
        progress = resume(runner, saved, os.path.join(out, "progress.json"), grid, steps_per_iteration, evaluate,
                          progress)
        write_json(os.path.join(out, "progress.json"), progress)  # keep any evaluations it redid
    for target in [g for g in grid if g > progress["done"]]:
        start = time.perf_counter()
        runner.current_learning_iteration = progress["done"]  # rsl-rl leaves it at the last iteration run
        runner.learn(target - progress["done"])
        progress["train_wall_time_s"] += time.perf_counter() - start
        progress["done"] = target
        start = time.perf_counter()
        result = evaluate(runner.get_inference_policy())
        progress["eval_wall_time_s"] += time.perf_counter() - start
        progress["history"].append(history_entry(result, target * steps_per_iteration))
        progress["last_result"] = result
        progress["cpu_seconds"] += time.process_time() - cpu_start
        cpu_start = time.process_time()
        write_json(os.path.join(out, "progress.json"), progress)
    if not any(os.path.isfile(os.path.join(folder, "model_final.pt")) for folder in train_folders(out)):
        runner.save(os.path.join(train_dir, "model_final.pt"))
    trained_steps = iterations * steps_per_iteration
    result = progress["last_result"]
    train_time, eval_time = progress["train_wall_time_s"], progress["eval_wall_time_s"]

    result.update(task=args.task, variant=args.variant, seed=args.seed, env_steps=trained_steps,
                  train_wall_time_s=train_time, steps_per_second=trained_steps / max(train_time, 1e-9),
                  eval_wall_time_s=eval_time, num_episodes=args.episodes, preferences=[list(p) for p in preferences],
                  history=progress["history"], resumed=progress["resumed"],
                  cpu_seconds=progress["cpu_seconds"] + time.process_time() - cpu_start,
                  cpu_seconds_complete=progress["cpu_seconds_complete"], fixed_preference=cfg.fixed_preference,
                  routing_scale=cfg.runner.actor.kwargs.get("routing_scale"), parameters=parameters,
                  expert_hidden_dims=list(cfg.runner.actor.hidden_dims),
                  preference_concentration=cfg.env.preference_concentration,
                  routing_mass=routing_mass_per_rollout(out))
    write_json(os.path.join(out, "result.json"), result)
    plot_front(result, cfg.env.objective_names, os.path.join(out, "pareto.png"))
    print(f"{args.task} {args.variant} seed {args.seed}: {trained_steps} steps in {train_time:.0f} s "
          f"({result['steps_per_second']:.0f} steps/s)")
    for row in result["rows"]:
        print("  lambda " + "/".join(f"{v:.2f}" for v in row["preference"]) + ": return "
              + ", ".join(f"{v:.1f}" for v in row["mean_return"]))
    print(f"  hypervolume {result['hypervolume']:.6g} (reference point {tuple(result['reference_point'])}), "
          f"sparsity {result['sparsity']:.6g}, {result['num_points']} non-dominated points, expected utility "
          f"{result['expected_utility']:.4f} (ranges {result['objective_range']}); {out}")
    return result


if __name__ == "__main__":
    main()
