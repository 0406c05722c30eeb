"""pchc-eval: the paper's evaluation of one or more checkpoints at fixed preferences."""

from __future__ import annotations

import argparse
import json
import math
import os

import numpy as np

from pchc_rsl.cli import arguments
from pchc_rsl.evaluation import (
    TASK_EVALUATION,
    aggregate,
    evaluation_preset,
    evenly_spaced_preferences,
    front_points,
    front_summary,
    markdown_table,
    run_episodes,
    run_return_episodes,
    switching_run,
)

PROG = "pchc-eval"


def build_parser() -> argparse.ArgumentParser:
    parser = arguments.Parser(
        prog=PROG,
        description="Evaluate checkpoints at fixed preferences under the task's evaluation preset (G1: no "
        "randomisation, no noise, the paper's pushes; toy: undiscounted returns of each goal); write results.json, "
        "table.md, pareto.png (and energy_curve.png for fall recovery, switching.png with --switch). A checkpoint "
        "trained with --fixed-preference is evaluated at that preference only: one point beside the fronts.",
    )
    parser.add_argument("checkpoints", nargs="+")
    parser.add_argument("--preferences", type=arguments.at_least_two, default=5,
                        help="evenly spaced preferences from (1,0) to (0,1) (default 5)")
    parser.add_argument("--preference", action="append", type=arguments.preference, metavar="L1,L2",
                        help="explicit preference(s) instead; repeatable")
    parser.add_argument("--num-envs", type=arguments.positive_int, default=64,
                        help="parallel envs (default 64: with --episodes 2, 128 episodes per preference, a few "
                             "minutes on 2 CPU cores; the paper uses 1000 envs)")
    parser.add_argument("--episodes", type=arguments.positive_int, default=2,
                        help="episodes per env and preference (default 2)")
    parser.add_argument("--seed", type=arguments.seed, default=0)
    parser.add_argument("--episode-length", type=arguments.positive_float, help="override the episode length (s)")
    parser.add_argument("--switch", action="store_true", help="also switch lambda (0,1) -> (1,0) mid-episode (G1)")
    parser.add_argument("--output", default="eval", help="folder for the results (default: eval)")
    parser.add_argument("--video", action="store_true", help="also write a video per checkpoint (see pchc-play)")
    parser.add_argument("-v", "--verbose", action="store_true", help="print the models and error tracebacks")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    if args.video and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        os.environ.setdefault("MUJOCO_GL", "egl")  # headless rendering; read when mujoco is first imported
    try:
        task, saved, preferences = check_inputs(args)
        videos = []
        if args.video:
            from pchc_rsl.cli.play import write_eval_videos

            os.makedirs(args.output, exist_ok=True)
            videos = write_eval_videos(args.checkpoints, preferences, args)
        results, curves, switching = [], {}, None
        for path in args.checkpoints:
            result, curve, switch = evaluate_checkpoint(path, saved[path], preferences, args)
            results.append(result)
            curves[result["name"]] = curve
            switching = switching or switch
    except (ValueError, FileNotFoundError) as error:
        if args.verbose:
            raise
        raise SystemExit(f"{PROG}: {error}") from None
    evaluation = TASK_EVALUATION[task]
    written = write_outputs(results, evaluation, curves, switching, args) + videos
    print(markdown_table(results, evaluation))
    for result in results:
        f = result["front"]
        print(f"{result['name']}: hypervolume {f['hypervolume']:.4g} (reference point {f['reference_point']}), "
              f"sparsity {f['sparsity']:.4g}, {f['num_points']} non-dominated points")
    print(f"{PROG}: wrote " + ", ".join(written))


def check_inputs(args) -> tuple[str, dict, list[tuple[float, ...]]]:
    """Everything that can be refused before evaluating: unreadable checkpoints, tasks without an evaluation or
    differing between checkpoints, preferences off the simplex, --switch on a task without it, a file as --output.
    Returns the task, each checkpoint's saved config and the preferences."""
    from pchc_rsl.cli.common import saved_config
    from pchc_rsl.preference import validate_preference
    from pchc_rsl.runners import load_checkpoint

    if os.path.exists(args.output) and not os.path.isdir(args.output):
        raise ValueError(f"--output {args.output} is a file; give a folder.")
    saved = {}
    for path in args.checkpoints:
        config = saved_config(path, load_checkpoint(path))
        if config["task"] not in TASK_EVALUATION:
            raise ValueError(f"{path} is for task '{config['task']}'; evaluation is defined for "
                             f"{', '.join(sorted(TASK_EVALUATION))}.")
        saved[path] = config
    evaluations = {id(TASK_EVALUATION[c["task"]]) for c in saved.values()}
    if len(evaluations) != 1:
        raise ValueError("checkpoints of different tasks " + str(sorted({c["task"] for c in saved.values()}))
                         + " cannot share one table; evaluate them separately.")
    task = next(iter(saved.values()))["task"]
    if args.switch and TASK_EVALUATION[task].episode_returns:
        raise ValueError(f"--switch measures falls and settling of the G1 tasks; task '{task}' has no such metrics.")
    if args.episode_length is not None and TASK_EVALUATION[task].episode_returns:
        raise ValueError(f"task '{task}' is evaluated on the episodes it was trained on; drop --episode-length.")
    num_objectives = len(next(iter(saved.values()))["env"]["objective_names"])
    if args.preference:
        preferences = []
        for p in args.preference:
            try:
                preferences.append(tuple(validate_preference(p, num_objectives).tolist()))
            except ValueError as error:
                raise ValueError(f"--preference {','.join(f'{x:g}' for x in p)}: {error}") from None
    else:
        preferences = evenly_spaced_preferences(args.preferences)
    return task, saved, preferences


def evaluation_config(config: dict, preset: str | None, num_envs: int, seed: int):
    """A checkpoint's saved config as pchc-eval runs it: the task's evaluation preset with this push preset (None:
    the config as trained), on the CPU, lambda not held."""
    from pchc_rsl.cli.common import restore_config

    cfg = restore_config(config)
    if preset is not None:
        cfg = evaluation_preset(cfg, preset, TASK_EVALUATION[config["task"]])
    cfg.num_envs, cfg.seed, cfg.device, cfg.fixed_preference = num_envs, seed, "cpu", None
    return cfg


def loaded_policy(path: str, cfg, verbose: bool = False):
    """(runner, deterministic policy) for ``cfg`` with the checkpoint at ``path`` loaded."""
    from pchc_rsl.cli.common import make_runner

    runner = make_runner(cfg, verbose=verbose)
    runner.load(path)
    return runner, runner.get_inference_policy()


def task_config_of(path: str, task_prefix: str, tool: str, what: str) -> dict:
    """A checkpoint's saved config; exits with a one-line error naming ``tool`` if its task is not ``what``."""
    from pchc_rsl.cli.common import saved_config
    from pchc_rsl.runners import load_checkpoint

    config = saved_config(path, load_checkpoint(path))
    if not config["task"].startswith(task_prefix):
        raise SystemExit(f"{tool}: {path} is for task '{config['task']}', not {what}.")
    return config


def evaluate_checkpoint(path: str, config: dict, preferences, args):
    task = config["task"]
    evaluation = TASK_EVALUATION[task]
    name = os.path.basename(os.path.dirname(os.path.abspath(path))) + "/" + os.path.basename(path)
    fixed = config.get("fixed_preference")
    if fixed is not None:  # other lambdas mean nothing to a policy that only ever saw this one
        preferences = [tuple(float(x) for x in fixed)]
    metrics = {p: {} for p in preferences}
    counts = {p: 0 for p in preferences}
    curve_prefs = {preferences[0], preferences[len(preferences) // 2], preferences[-1]}
    curves, switch = {}, None
    presets = evaluation.push_presets or [None]
    for preset_index, preset in enumerate(presets):
        cfg = evaluation_config(config, preset, args.num_envs, args.seed)
        if args.episode_length is not None:
            cfg.env.episode_length_s = args.episode_length
        runner, policy = loaded_policy(path, cfg, verbose=args.verbose)
        run = run_return_episodes if evaluation.episode_returns else run_episodes
        for lam in preferences:
            label = f"{name} {preset or ''} {lam}".replace("  ", " ")
            episodes, curve = run(runner.env, policy, lam, args.episodes, progress=label)
            summary = aggregate(episodes)
            if preset is not None:
                metrics[lam].update({f"{preset}/{k}": v for k, v in summary.items()})
            if preset_index == 0:
                metrics[lam].update(summary)
                counts[lam] = len(episodes)
                if lam in curve_prefs:
                    curves[lam] = curve
        if preset_index == 0 and args.switch and fixed is None:
            env = runner.env
            switch = switching_run(env, policy, (0.0, 1.0), (1.0, 0.0), env.max_episode_length // 2)
            switch["objectives"] = list(env.cfg.objective_names)
    rows = [{"preference": list(lam), "metrics": metrics[lam], "episodes": counts[lam]} for lam in preferences]
    result = {"name": name, "checkpoint": os.path.abspath(path), "rows": rows}
    result["front"] = front_summary(front_points(rows, evaluation), evaluation)
    return result, curves, switch


def write_outputs(results, evaluation, curves, switching, args) -> list[str]:
    """results.json (strict JSON: null where a metric is undefined), table.md and the plots; the paths written."""
    os.makedirs(args.output, exist_ok=True)
    path = os.path.join(args.output, "results.json")
    with open(path, "w") as f:
        json.dump(_finite_or_null({"table": evaluation.table, "seed": args.seed, "results": results,
                                   "switching": _switching_json(switching)}), f, indent=2, allow_nan=False)
    written = [path]
    path = os.path.join(args.output, "table.md")
    with open(path, "w") as f:
        f.write(markdown_table(results, evaluation))
    written.append(path)
    written.append(plot_pareto(results, evaluation, os.path.join(args.output, "pareto.png")))
    if "energy_overall" in evaluation.columns:
        written.append(plot_energy_curves(curves, os.path.join(args.output, "energy_curve.png")))
    if switching is not None:
        written.append(plot_switching(switching, os.path.join(args.output, "switching.png")))
    return written


def _finite_or_null(value):
    """A copy of nested dicts/lists with NaN and inf as None (JSON has no NaN) and numpy scalars as floats."""
    if isinstance(value, dict):
        return {k: _finite_or_null(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_null(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


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
    empty = _empty_front_reason(results, evaluation)
    if empty:
        ax.text(0.5, 0.5, empty, transform=ax.transAxes, ha="center", va="center", fontsize=8, wrap=True)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _empty_front_reason(results, evaluation) -> str:
    """Why there is no point to plot, or '' when there is one: the front metric(s) undefined at every preference."""
    keys = [key for key, _ in evaluation.front]
    rows = [row for result in results for row in result["rows"]]
    if any(all(math.isfinite(row["metrics"].get(key, math.nan)) for key in keys) for row in rows):
        return ""
    undefined = [key for key in keys if not any(math.isfinite(r["metrics"].get(key, math.nan)) for r in rows)]
    return (f"No point to plot: {' and '.join(undefined)} undefined at every preference.\n"
            "No episode lasted long enough to measure it\n(e.g. every episode fell before the first push).")


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
    return path


def plot_switching(switch, path):
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5.5, 3.5))
    t = np.arange(len(switch["curve"])) * switch["dt"]
    for i, name in enumerate(switch["objectives"]):
        ax.plot(t, switch["curve"][:, i], label=f"r_{name}")
    ax.axvline(switch["switch_step"] * switch["dt"], color="k", ls="--", label="lambda (0,1) -> (1,0)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("objective reward per step (mean over envs)")
    settle = switch["settle_time_s"]
    settle = "n/a (no continuous objective)" if settle != settle else f"{settle:.2f} s"
    ax.set_title(f"falls {switch['falls']}, settle time {settle}", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


if __name__ == "__main__":
    main()
