"""Evaluating a checkpoint: its saved config under the evaluation preset, its policy loaded, every preference and
push preset run; and the env and policy of a checkpoint as pchc-play, the viewers and the tools show it."""

from __future__ import annotations

import dataclasses
import os

from pchc_rsl.evaluation.presets import TASK_EVALUATION, evaluation_preset
from pchc_rsl.evaluation.report import front_points, front_summary
from pchc_rsl.evaluation.runs import run_preference_batch, run_return_episodes, switching_run
from pchc_rsl.evaluation.statistics import aggregate
from pchc_rsl.runners import load_checkpoint
from pchc_rsl.training.build import for_running, make_runner, placed, restore_config, saved_config
from pchc_rsl.training.overrides import apply_overrides
from pchc_rsl.utils.files import recorded_path

TOY_STEPS_PER_SECOND = 10
"""The toy has no physical time: an episode length in seconds, and its video, count this many steps per second."""


def evaluation_config(config: dict, preset: str | None, num_envs: int, seed: int, overrides: list[str] = (),
                      device: str = "cpu"):
    """A checkpoint's saved config as pchc-eval runs it: the task's evaluation preset with this push preset (None:
    the config as trained), then the ``KEY=VALUE`` overrides (a deployment shift, another push), lambda not held."""
    cfg = restore_config(config)
    if preset is not None:
        cfg = evaluation_preset(cfg, preset, TASK_EVALUATION[config["task"]])
    placed(cfg, device)  # a GPU-trained policy on the CPU: C MuJoCo (env.physics=warp keeps Warp)
    apply_overrides(cfg, list(overrides))
    cfg.num_envs, cfg.seed, cfg.device, cfg.fixed_preference = num_envs, seed, device, None
    return cfg


def loaded_policy(path: str, cfg, verbose: bool = False):
    """(runner, deterministic policy) for ``cfg`` with the checkpoint at ``path`` loaded."""
    runner = make_runner(for_running(cfg), verbose=verbose)
    runner.load(path)
    return runner, runner.get_inference_policy()


def task_config_of(path: str, task_prefix: str, tool: str, what: str) -> dict:
    """A checkpoint's saved config; exits with a one-line error naming ``tool`` if its task is not ``what``."""
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
                        verbose: bool = False, device: str = "cpu", presets: list[str] | None = None,
                        on_preset=None):
    """Every preference under each of the task's push presets, after ``overrides``: one result (rows of metrics per
    preference, the Pareto summary), the step-wise reward curves, the switch run. ``presets`` names other presets
    of the task to play the task's roles in order (``["mild-v1", "strong-v1"]``: metrics still under mild/ and
    strong/), or fewer (``["mild"]``: the first role only). ``on_preset(result, curves, switched)`` is called with
    the result so far after each preset but the last (what an interrupted evaluation can still write)."""
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
    batched = not evaluation.episode_returns  # the G1 envs hold lambda per env: every preference in one batch
    for preset_index, (role, preset) in enumerate(zip(roles, presets)):
        cfg = evaluation_config(config, preset, num_envs * (len(preferences) if batched else 1), seed, overrides,
                                device)
        if episode_length is not None:
            cfg.env.episode_length_s = episode_length
        runner, policy = loaded_policy(path, cfg, verbose=verbose)
        if batched:
            label = f"{name} {preset or ''} {len(preferences)} preferences x {num_envs} envs".replace("  ", " ")
            runs = zip(preferences, run_preference_batch(runner.env, policy, preferences, episodes, progress=label))
        else:
            runs = ((lam, run_return_episodes(runner.env, policy, lam, episodes, progress=f"{name} {lam}"))
                    for lam in preferences)
        for lam, (finished, curve) in runs:
            summary = aggregate(finished)
            if preset is not None:
                metrics[lam].update({f"{role}/{k}": v for k, v in summary.items()})
            if preset_index == 0:
                metrics[lam].update(summary)
                counts[lam] = len(finished)
                if lam in curve_prefs:
                    curves[lam] = curve
        if preset_index == 0 and switch and fixed is None:
            if batched:  # the switch run is one preference pair on num_envs envs
                cfg.num_envs = num_envs
                runner, policy = loaded_policy(path, cfg, verbose=verbose)
            env = runner.env
            switched = switching_run(env, policy, (0.0, 1.0), (1.0, 0.0), env.max_episode_length // 2)
            switched["objectives"] = list(env.cfg.objective_names)
        if on_preset is not None and preset_index < len(roles) - 1:
            on_preset(_result(name, path, preferences, metrics, counts, evaluation, roles[:preset_index + 1],
                              presets[:preset_index + 1]), curves, switched)
    return _result(name, path, preferences, metrics, counts, evaluation, roles, presets), curves, switched


def _result(name, path, preferences, metrics, counts, evaluation, roles, presets) -> dict:
    """The result of the presets run so far: rows per preference and the Pareto summary."""
    rows = [{"preference": list(lam), "metrics": metrics[lam], "episodes": counts[lam]} for lam in preferences]
    result = {"name": name, "checkpoint": recorded_path(path), "rows": rows,
              "push_presets": {role: {"preset": preset, "push": _preset_record(evaluation.pushes.get(preset))}
                               for role, preset in zip(roles, presets) if role is not None}}
    result["front"] = front_summary(front_points(rows, evaluation), evaluation)
    return result


def _preset_record(preset) -> dict | None:
    """A push preset as plain data for results.json."""
    return None if preset is None else dataclasses.asdict(preset)


def load_policy(path: str, num_envs: int, seed: int, episode_length_s: float | None, push_every: float | None,
                overrides: list[str] = ()):
    """The checkpoint's env under pchc-eval's evaluation preset (its first push preset) and ``overrides``, and its
    inference policy.

    Returns (task, env, policy); ValueError (one line) for a task without an evaluation preset or a bad override."""
    config = load_checkpoint(path).get("config") or {}
    task = config.get("task")
    if task != "toy" and task not in TASK_EVALUATION:
        shown = ", ".join(sorted(TASK_EVALUATION) + ["toy"])
        raise ValueError(f"{path} is for task '{task}'; a policy can be shown for {shown}.")
    cfg = restore_config(config)
    if task == "toy":
        if episode_length_s is not None:
            cfg.env.episode_length = max(1, round(episode_length_s * TOY_STEPS_PER_SECOND))
    else:
        evaluation = TASK_EVALUATION[task]
        cfg = evaluation_preset(cfg, evaluation.push_presets[0], evaluation)
        if episode_length_s is not None:
            cfg.env.episode_length_s = episode_length_s
        if push_every is not None:
            interval = push_every if push_every > 0 else 1e9  # 0: never by itself, still on a key press
            cfg.env.push.interval_s = (interval, interval)
    placed(cfg, "cpu")
    apply_overrides(cfg, list(overrides))
    cfg.num_envs, cfg.seed, cfg.device = num_envs, seed, "cpu"
    runner, policy = loaded_policy(path, cfg)
    return task, runner.env, policy


def check_objectives(env, preferences, path: str) -> None:
    """ValueError unless every preference has one entry per objective of the env."""
    m = env.num_objectives
    for lam in preferences:
        if len(lam) != m:
            names = ", ".join(env.cfg.objective_names)
            raise ValueError(f"preference {lam} has {len(lam)} entries; {path} has {m} objectives "
                             f"({names}): pass --preference with {m} numbers summing to 1.")
