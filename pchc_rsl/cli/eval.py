"""pchc-eval: the paper's evaluation of one or more checkpoints at fixed preferences."""

from __future__ import annotations

import argparse
import json
import os

import numpy as np

from pchc_rsl.evaluation import (
    TASK_EVALUATION,
    aggregate,
    evaluation_preset,
    evenly_spaced_preferences,
    front_points,
    front_summary,
    markdown_table,
    run_episodes,
    switching_run,
)
from pchc_rsl.preference import validate_preference
from pchc_rsl.runners import load_checkpoint


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pchc-eval",
        description="Evaluate checkpoints at fixed preferences under the task's evaluation preset (no randomisation, "
        "no noise, the paper's pushes); write results.json, table.md, pareto.png (and energy_curve.png for fall "
        "recovery, switching.png with --switch).",
    )
    parser.add_argument("checkpoints", nargs="+")
    parser.add_argument("--preferences", type=int, default=5, help="evenly spaced preferences from (1,0) to (0,1)")
    parser.add_argument("--preference", action="append", metavar="L1,L2", help="explicit preference(s); repeatable")
    parser.add_argument("--num-envs", type=int, default=16)
    parser.add_argument("--episodes", type=int, default=1, help="episodes per env and preference")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--episode-length", type=float, help="override the episode length (s)")
    parser.add_argument("--switch", action="store_true", help="also switch lambda (0,1) -> (1,0) mid-episode")
    parser.add_argument("--output", default="eval")
    parser.add_argument("--video", action="store_true", help="also write a video per checkpoint (see pchc-play)")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    preferences = (
        [tuple(validate_preference([float(x) for x in p.split(",")], 2).tolist()) for p in args.preference]
        if args.preference
        else evenly_spaced_preferences(args.preferences)
    )
    os.makedirs(args.output, exist_ok=True)
    if args.video:  # first: a headless run must pick MUJOCO_GL=egl before mujoco is imported
        from pchc_rsl.cli.play import write_eval_videos

        write_eval_videos(args.checkpoints, preferences, args)
    results, tasks, curves, switching = [], set(), {}, None
    for path in args.checkpoints:
        result, task, curve, switch = evaluate_checkpoint(path, preferences, args)
        results.append(result)
        tasks.add(task)
        curves[result["name"]] = curve
        switching = switching or switch
    if len(tasks) != 1:
        raise SystemExit(f"pchc-eval: checkpoints of different tasks {sorted(tasks)} cannot share one table.")
    evaluation = TASK_EVALUATION[tasks.pop()]
    with open(os.path.join(args.output, "results.json"), "w") as f:
        json.dump({"table": evaluation.table, "seed": args.seed, "results": results,
                   "switching": _switching_json(switching)}, f, indent=2)
    with open(os.path.join(args.output, "table.md"), "w") as f:
        f.write(markdown_table(results, evaluation))
    plot_pareto(results, evaluation, os.path.join(args.output, "pareto.png"))
    if "energy_overall" in evaluation.columns:
        plot_energy_curves(curves, os.path.join(args.output, "energy_curve.png"))
    if switching is not None:
        plot_switching(switching, os.path.join(args.output, "switching.png"))
    print(markdown_table(results, evaluation))
    for result in results:
        f = result["front"]
        print(f"{result['name']}: hypervolume {f['hypervolume']:.4g} (reference point {f['reference_point']}), "
              f"sparsity {f['sparsity']:.4g}, {f['num_points']} non-dominated points")
    print(f"pchc-eval: wrote {args.output}/results.json, table.md, pareto.png")


def evaluate_checkpoint(path: str, preferences, args):
    from pchc_rsl.cli.common import make_runner
    from pchc_rsl.cli.export_onnx import restore_config
    from pchc_rsl.configs import task_config

    config = load_checkpoint(path).get("config") or {}
    task = config.get("task")
    if task not in TASK_EVALUATION:
        raise SystemExit(f"pchc-eval: {path} is for task '{task}'; evaluation is defined for {sorted(TASK_EVALUATION)}.")
    evaluation = TASK_EVALUATION[task]
    name = os.path.splitext(os.path.basename(os.path.dirname(os.path.abspath(path))))[0] + "/" + os.path.basename(path)
    metrics = {p: {} for p in preferences}
    curve_prefs = {preferences[0], preferences[len(preferences) // 2], preferences[-1]}
    curves, switch = {}, None
    for preset_index, preset in enumerate(evaluation.push_presets):
        cfg = task_config(task)
        restore_config(cfg, config)
        cfg = evaluation_preset(cfg, preset, evaluation)
        cfg.num_envs, cfg.seed = args.num_envs, args.seed
        if args.episode_length is not None:
            cfg.env.episode_length_s = args.episode_length
        runner = make_runner(cfg)
        runner.load(path)
        policy = runner.get_inference_policy()
        for lam in preferences:
            episodes, curve = run_episodes(runner.env, policy, lam, args.episodes, progress=f"{name} {preset} {lam}")
            summary = aggregate(episodes)
            metrics[lam].update({f"{preset}/{k}": v for k, v in summary.items()})
            if preset_index == 0:
                metrics[lam].update(summary)
                if lam in curve_prefs:
                    curves[lam] = curve
        if preset_index == 0 and args.switch:
            env = runner.env
            switch = switching_run(env, policy, (0.0, 1.0), (1.0, 0.0), env.max_episode_length // 2)
            switch["objectives"] = list(env.cfg.objective_names)
    rows = [{"preference": list(lam), "metrics": metrics[lam]} for lam in preferences]
    result = {"name": name, "checkpoint": os.path.abspath(path), "rows": rows}
    result["front"] = front_summary(front_points(rows, evaluation), evaluation)
    return result, task, curves, switch


def _switching_json(switch):
    if switch is None:
        return None
    return {"falls": switch["falls"], "settle_time_s": switch["settle_time_s"], "objectives": switch["objectives"],
            "switch_time_s": switch["switch_step"] * switch["dt"], "objective_curves": switch["curve"].tolist()}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_pareto(results, evaluation, path):
    plt = _pyplot()
    (a, _), (b, _) = evaluation.front
    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    for result in results:
        xs = [r["metrics"].get(a, np.nan) for r in result["rows"]]
        ys = [r["metrics"].get(b, np.nan) for r in result["rows"]]
        f = result["front"]
        ax.plot(xs, ys, "o-", label=f"{result['name']}: HV {f['hypervolume']:.3g}, S {f['sparsity']:.3g}")
        for row, x, y in zip(result["rows"], xs, ys):
            ax.annotate("(" + ", ".join(f"{v:.2f}" for v in row["preference"]) + ")", (x, y), fontsize=7)
    ax.set_xlabel(evaluation.columns.get(a, a))
    ax.set_ylabel(evaluation.columns.get(b, b))
    ax.set_title(f"{evaluation.table}; HV reference point {evaluation.reference_point}", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_energy_curves(curves, path):
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5.5, 3.5))
    for name, by_preference in curves.items():
        for lam, curve in sorted(by_preference.items()):
            ax.plot(-curve[:, 1], label=f"{name} {lam}")
    ax.set_xlabel("policy step")
    ax.set_ylabel("-r_energy per step")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_switching(switch, path):
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5.5, 3.5))
    t = np.arange(len(switch["curve"])) * switch["dt"]
    for i, name in enumerate(switch["objectives"]):
        ax.plot(t, switch["curve"][:, i], label=f"r_{name}")
    ax.axvline(switch["switch_step"] * switch["dt"], color="k", ls="--", label="lambda (0,1) -> (1,0)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("objective reward per step (mean over envs)")
    ax.set_title(f"falls {switch['falls']}, settle time {switch['settle_time_s']:.2f} s", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
