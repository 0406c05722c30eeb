"""Evaluating a checkpoint: its saved config under the evaluation preset, its policy loaded, every preference and
push preset run."""

from __future__ import annotations

import os

from pchc_rsl.evaluation.presets import TASK_EVALUATION, evaluation_preset
from pchc_rsl.evaluation.report import front_points, front_summary
from pchc_rsl.evaluation.runs import run_episodes, run_return_episodes, switching_run
from pchc_rsl.evaluation.statistics import aggregate


def evaluation_config(config: dict, preset: str | None, num_envs: int, seed: int, overrides: list[str] = (),
                      device: str = "cpu"):
    """A checkpoint's saved config as pchc-eval runs it: the task's evaluation preset with this push preset (None:
    the config as trained), then the ``KEY=VALUE`` overrides (a deployment shift, another push), lambda not held."""
    from pchc_rsl.cli.common import restore_config
    from pchc_rsl.cli.overrides import apply_overrides

    cfg = restore_config(config)
    if preset is not None:
        cfg = evaluation_preset(cfg, preset, TASK_EVALUATION[config["task"]])
    apply_overrides(cfg, list(overrides))
    cfg.num_envs, cfg.seed, cfg.device, cfg.fixed_preference = num_envs, seed, device, None
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


def trained_preference(config: dict) -> tuple[float, ...] | None:
    """The one preference a checkpoint trained with --fixed-preference saw (other lambdas mean nothing to such a
    policy: pchc-eval and pchc-play show it there only); None for a preference-conditioned policy."""
    fixed = config.get("fixed_preference")
    return None if fixed is None else tuple(float(x) for x in fixed)


def evaluate_checkpoint(path: str, config: dict, preferences, num_envs: int = 64, episodes: int = 2, seed: int = 0,
                        episode_length: float | None = None, switch: bool = False, overrides: list[str] = (),
                        verbose: bool = False, device: str = "cpu", presets: list[str] | None = None):
    """Every preference under each of the task's push presets, after ``overrides``: one result (rows of metrics per
    preference, the Pareto summary), the step-wise reward curves, the switch run. ``presets`` names other presets
    of the task to play the task's roles in order (``["mild-v1", "strong-v1"]``: metrics still under mild/ and
    strong/), or fewer (``["mild"]``: the first role only)."""
    task = config["task"]
    evaluation = TASK_EVALUATION[task]
    name = os.path.basename(os.path.dirname(os.path.abspath(path))) + "/" + os.path.basename(path)
    fixed = trained_preference(config)
    if fixed is not None:
        preferences = [fixed]
    metrics = {p: {} for p in preferences}
    counts = {p: 0 for p in preferences}
    curve_prefs = {preferences[0], preferences[len(preferences) // 2], preferences[-1]}
    curves, switched = {}, None
    roles = evaluation.push_presets or [None]
    presets = presets or roles
    for preset_index, (role, preset) in enumerate(zip(roles, presets)):
        cfg = evaluation_config(config, preset, num_envs, seed, overrides, device)
        if episode_length is not None:
            cfg.env.episode_length_s = episode_length
        runner, policy = loaded_policy(path, cfg, verbose=verbose)
        run = run_return_episodes if evaluation.episode_returns else run_episodes
        for lam in preferences:
            label = f"{name} {preset or ''} {lam}".replace("  ", " ")
            finished, curve = run(runner.env, policy, lam, episodes, progress=label)
            summary = aggregate(finished)
            if preset is not None:
                metrics[lam].update({f"{role}/{k}": v for k, v in summary.items()})
            if preset_index == 0:
                metrics[lam].update(summary)
                counts[lam] = len(finished)
                if lam in curve_prefs:
                    curves[lam] = curve
        if preset_index == 0 and switch and fixed is None:
            env = runner.env
            switched = switching_run(env, policy, (0.0, 1.0), (1.0, 0.0), env.max_episode_length // 2)
            switched["objectives"] = list(env.cfg.objective_names)
    rows = [{"preference": list(lam), "metrics": metrics[lam], "episodes": counts[lam]} for lam in preferences]
    result = {"name": name, "checkpoint": os.path.abspath(path), "rows": rows,
              "push_presets": {role: {"preset": preset, "speed_window": evaluation.pushes.get(preset)}
                               for role, preset in zip(roles, presets) if role is not None}}
    result["front"] = front_summary(front_points(rows, evaluation), evaluation)
    return result, curves, switched

