"""The paper's evaluation: a policy at fixed preferences under the task's evaluation preset, Pareto metrics,
Table I / II, and dynamic preference switching.

Works on any env that follows the contract (set_preference, extras["episode_metrics"] at episode ends); the task
specifics (which metrics form the front, the table columns, the evaluation preset) are in TASK_EVALUATION.
"""

from __future__ import annotations

import copy
import math
import sys
from dataclasses import dataclass, field

import numpy as np
import torch

from pchc_rsl.pareto import hypervolume, non_dominated, sparsity


@dataclass
class TaskEvaluation:
    """What to measure for one task family."""

    table: str
    columns: dict[str, str]
    """metric key -> column title of the paper's table."""
    front: tuple[tuple[str, float], tuple[str, float]]
    """The two objective metrics of the Pareto plot, each with the sign that makes it 'more is better'."""
    reference_point: tuple[float, float]
    """Hypervolume reference point in the signed front coordinates (stated with every figure)."""
    episode_returns: bool = False
    """Measure each objective's undiscounted episode return (run_return_episodes) instead of the env's
    episode_metrics, with the task's config as it is (no evaluation preset): for envs without task metrics."""
    push_presets: list[str] = field(default_factory=lambda: ["mild"])
    command: tuple[float, float, float] | None = None
    push_only_when_standing: bool = False
    """Push the robot once it stands (fall recovery), not while it is still on the floor."""


WALK_EVALUATION = TaskEvaluation(
    table="Table II (walking)",
    columns={"stride_length": "Avg. Stride (m)", "push_deviation": "Traj. Deviation (m)", "fall_rate": "Falls (%)"},
    front=(("push_deviation", -1.0), ("stride_length", 1.0)),
    reference_point=(-2.0, 0.0),
    push_presets=["mild"],
    command=(0.5, 0.0, 0.0),
)
FALL_RECOVERY_EVALUATION = TaskEvaluation(
    table="Table I (fall recovery)",
    columns={
        "energy_overall": "Avg. Energy Overall (J/s)",
        "energy_recovery": "Avg. Energy Fall Recovery (J/s)",
        "energy_standing": "Avg. Energy Recovery (J/s)",
        "torque_overall": "Avg. Torque Overall (Nm)",
        "torque_recovery": "Avg. Torque Fall Recovery (Nm)",
        "torque_standing": "Avg. Torque Recovery (Nm)",
        "mild/com_displacement": "COM displacement (m)",
        "mild/success": "Success, mild pushes (%)",
        "strong/success": "Success, strong pushes (%)",
    },
    front=(("energy_overall", -1.0), ("mild/com_displacement", -1.0)),
    reference_point=(-3000.0, -3.0),
    push_presets=["mild", "strong"],
    push_only_when_standing=True,
)
TOY_EVALUATION = TaskEvaluation(
    table="Toy task (two goals)",
    columns={"goal_a": "Return goal A (undiscounted)", "goal_b": "Return goal B (undiscounted)"},
    front=(("goal_a", 1.0), ("goal_b", 1.0)),
    reference_point=(-60.0, -60.0),
    push_presets=[],
    episode_returns=True,
)
TASK_EVALUATION = {
    "toy": TOY_EVALUATION,
    "g1-walk": WALK_EVALUATION,
    "g1-walk-fast": WALK_EVALUATION,
    "g1-fall-recovery": FALL_RECOVERY_EVALUATION,
    "g1-fall-recovery-fast": FALL_RECOVERY_EVALUATION,
}


def evenly_spaced_preferences(count: int) -> list[tuple[float, float]]:
    """(1, 0), ..., (0, 1) in ``count`` steps."""
    if count < 2:
        raise ValueError(f"Need at least 2 preferences, got {count}.")
    return [(1 - i / (count - 1), i / (count - 1)) for i in range(count)]


def evaluation_preset(cfg, push_preset: str, evaluation: TaskEvaluation):
    """A copy of a task config for evaluation: no randomisation, no noise, no curriculum, the preset's pushes."""
    from pchc_rsl.envs.g1_env import PUSH_PRESETS

    cfg = copy.deepcopy(cfg)
    env = cfg.env
    env.randomization.enabled = False
    env.observation_noise = 0.0
    env.preference_resample_prob = 0.0
    env.push = copy.deepcopy(PUSH_PRESETS[push_preset])
    env.push.only_when_standing = evaluation.push_only_when_standing
    if hasattr(env, "curriculum"):
        env.curriculum = False
    if evaluation.command is not None:
        vx, vy, wz = evaluation.command
        env.command_ranges = {"lin_vel_x": (vx, vx), "lin_vel_y": (vy, vy), "ang_vel_z": (wz, wz)}
    return cfg


RATE_METRICS = {"success": "success", "fell": "fall_rate"}
"""Per-episode 0/1 outcomes reported as percentages (metric key -> reported key)."""
Z95 = 1.959963984540054


def aggregate(episodes: list[dict[str, float]]) -> dict:
    """Mean of each metric over episodes, ignoring NaN (a metric undefined in an episode, e.g. no push), with its
    95% interval under ``KEY_ci95`` ([low, high]): Student's t for measured quantities, Wilson's score interval for
    the 0/1 outcomes 'success' and 'fell', which become percentages ('fell' is reported as 'fall_rate')."""
    keys = sorted({k for e in episodes for k in e})
    out: dict = {}
    for key in keys:
        values = np.array([e[key] for e in episodes if key in e], dtype=float)
        values = values[~np.isnan(values)]
        n = len(values)
        mean = float(values.mean()) if n else float("nan")
        if key in RATE_METRICS:
            interval = [100.0 * x for x in wilson_interval(mean, n)]
            key, mean = RATE_METRICS[key], 100.0 * mean
        elif n >= 2:
            from scipy import stats

            half = float(stats.t.ppf(0.975, n - 1) * values.std(ddof=1) / math.sqrt(n))
            interval = [mean - half, mean + half]
        else:
            interval = [float("nan"), float("nan")]
        out[key] = mean
        out[f"{key}_ci95"] = interval
    return out


def wilson_interval(p: float, n: int) -> tuple[float, float]:
    """95% Wilson score interval of a proportion p observed in n trials (stays inside [0, 1], also at 0 or 1)."""
    if n == 0 or p != p:
        return float("nan"), float("nan")
    z2 = Z95 * Z95
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = Z95 * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    return centre - half, centre + half


def run_episodes(env, policy, preference, episodes: int, progress: str = "") -> tuple[list[dict], np.ndarray]:
    """Roll the deterministic policy until every env finished ``episodes`` episodes at ``preference``.

    Returns one metric dict per finished episode and the mean per-step reward groups [T, 1 + m] of the first
    episode round (for step-wise curves)."""
    finished = torch.zeros(env.num_envs, dtype=torch.long)
    results, curve = [], []
    steps = 0
    total = episodes * env.max_episode_length
    with torch.inference_mode():  # the env's buffers are inference tensors once stepped in this mode
        env.set_preference(preference)
        env.reset()
        obs = env.get_observations()
        while (finished < episodes).any():
            obs, _, _, extras = env.step(policy(obs))
            if steps < env.max_episode_length:
                curve.append(extras["reward_groups"].mean(0).numpy())
            steps += 1
            done = extras["episode_metrics"]
            for row, env_id in enumerate(done["env_ids"].tolist()):
                if finished[env_id] < episodes:
                    results.append({k: float(v[row]) for k, v in done.items() if k != "env_ids"})
                    finished[env_id] += 1
            if progress and steps % 25 == 0:
                _progress(progress, min(steps, total), total)
    if progress:
        _progress(progress, total, total, end=True)
    return results, np.array(curve)


def _progress(label: str, done: int, total: int, end: bool = False) -> None:
    """A bar redrawn in place on a terminal; in a log file (not a terminal) only the finished line."""
    if not end and not sys.stderr.isatty():
        return
    width = 30
    filled = int(width * done / max(total, 1))
    sys.stderr.write(f"\r{label} [{'#' * filled}{'.' * (width - filled)}] {done}/{total}")
    if end:
        sys.stderr.write("\n")
    sys.stderr.flush()


def front_points(rows: list[dict], evaluation: TaskEvaluation) -> np.ndarray:
    """[n, 2] signed objective metrics (more is better) of the evaluated preferences."""
    (a, sa), (b, sb) = evaluation.front
    return np.array([[sa * r["metrics"][a], sb * r["metrics"][b]] for r in rows])


def front_summary(points: np.ndarray, evaluation: TaskEvaluation) -> dict:
    """Hypervolume (with its reference point) and sparsity of the non-dominated subset of ``points``."""
    finite = points[np.isfinite(points).all(axis=1)]
    if len(finite) == 0:
        return {"hypervolume": 0.0, "sparsity": float("nan"), "reference_point": list(evaluation.reference_point),
                "num_points": 0}
    front = non_dominated(finite)
    return {
        "hypervolume": hypervolume(front, evaluation.reference_point),
        "sparsity": sparsity(front),
        "reference_point": list(evaluation.reference_point),
        "num_points": int(len(front)),
    }


def markdown_table(results: list[dict], evaluation: TaskEvaluation) -> str:
    """The paper's table: one row per (checkpoint, preference), each figure with its 95% interval."""
    header = ["Policy", "Preference", *evaluation.columns.values(), "Episodes"]
    lines = [f"{evaluation.table}; mean ± 95% interval half-width (t), rates with the Wilson 95% interval", "",
             "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for result in results:
        for row in result["rows"]:
            lam = "(" + ", ".join(f"{x:.2f}" for x in row["preference"]) + ")"
            metrics = row["metrics"]
            cells = [format_metric(metrics.get(key, math.nan), metrics.get(f"{key}_ci95"), key)
                     for key in evaluation.columns]
            lines.append("| " + " | ".join([result["name"], lam, *cells, str(row.get("episodes", ""))]) + " |")
    return "\n".join(lines) + "\n"


def format_metric(value: float, interval: list[float] | None = None, key: str = "", digits: int = 2) -> str:
    """'mean ± half-width', or 'rate [low, high]' for rates (their intervals are not symmetric); 'n/a' where
    undefined, the bare mean where the interval is (missing, or NaN / None as results.json stores it)."""
    if value != value:
        return "n/a"
    if not interval or interval[0] is None or interval[0] != interval[0]:
        return f"{value:.{digits}f}"
    if key.endswith(("success", "fall_rate")):
        return f"{value:.1f} [{interval[0]:.1f}, {interval[1]:.1f}]"
    return f"{value:.{digits}f} ± {(interval[1] - interval[0]) / 2:.{digits}f}"


def switching_run(env, policy, before, after, switch_step: int) -> dict:
    """One episode at ``before`` switched to ``after`` at ``switch_step``: per-step mean objective rewards [T, m],
    falls, and the time (s) after the switch until the objective curves settle (see ``settle_time``)."""
    curve, falls = [], 0
    with torch.inference_mode():
        env.set_preference(before)
        env.reset()
        obs = env.get_observations()
        for step in range(env.max_episode_length - 1):
            if step == switch_step:
                env.set_preference(after)
            obs, _, _, extras = env.step(policy(obs))
            curve.append(extras["reward_groups"][:, 1:].mean(0).numpy())
            falls += int(extras["episode_metrics"]["fell"].sum())
    curve = np.array(curve)
    return {"curve": curve, "falls": falls, "settle_time_s": settle_time(curve, switch_step, env.dt), "dt": env.dt,
            "switch_step": switch_step}


def settle_time(curve: np.ndarray, switch_step: int, dt: float, continuous_share: float = 0.9) -> float:
    """Seconds after ``switch_step`` until every continuous objective of ``curve`` ([T, m]) has settled: its trailing
    1 s average stays within 10% of its post-switch range of its final 1 s average. The 1 s average spans a few
    footsteps, so per-step events (touchdowns) count as continuous; objectives whose 1 s average is zero on more than
    1 - ``continuous_share`` of the steps after the switch (the response to pushes a few seconds apart) have no level
    to settle to and are left out. NaN when no objective is continuous or the episode is too short."""
    window = max(1, int(round(1.0 / dt)))
    if switch_step < window - 1 or len(curve) - switch_step < window:
        return float("nan")  # an episode too short to hold 1 s on both sides of the switch
    kernel = np.ones(window) / window
    average = np.stack([np.convolve(c, kernel, mode="valid") for c in curve.T], axis=1)  # ends at step window-1
    after = average[switch_step - (window - 1):]
    continuous = (after != 0).mean(axis=0) >= continuous_share
    if not continuous.any():
        return float("nan")
    after = after[:, continuous]
    tolerance = 0.1 * np.ptp(after, axis=0)
    unsettled = np.flatnonzero((np.abs(after - after[-1]) > tolerance).any(axis=1))
    return float((unsettled[-1] + 1) * dt) if len(unsettled) else 0.0


def run_return_episodes(env, policy, preference, episodes: int, progress: str = "") -> tuple[list[dict], np.ndarray]:
    """Like run_episodes, for an env without episode_metrics: each finished episode's undiscounted return of every
    objective (summed from extras["reward_groups"]), keyed by ``env.cfg.objective_names``."""
    names = list(env.cfg.objective_names)
    finished = torch.zeros(env.num_envs, dtype=torch.long)
    sums = torch.zeros(env.num_envs, len(names))
    results, curve = [], []
    with torch.inference_mode():
        env.set_preference(preference)
        env.reset()
        obs = env.get_observations()
        steps = 0
        while (finished < episodes).any():
            obs, _, dones, extras = env.step(policy(obs))
            groups = extras["reward_groups"]
            if steps < env.max_episode_length:
                curve.append(groups.mean(0).numpy())
            steps += 1
            sums += groups[:, 1:]
            for env_id in dones.nonzero(as_tuple=False).flatten().tolist():
                if finished[env_id] < episodes:
                    results.append({name: float(sums[env_id, i]) for i, name in enumerate(names)})
                    finished[env_id] += 1
            sums[dones.bool()] = 0.0
    if progress:
        _progress(progress, 1, 1, end=True)
    return results, np.array(curve)
