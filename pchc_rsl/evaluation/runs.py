"""Rolling a policy in an env at fixed preferences: finished episodes' metrics, returns, and a preference switch."""

from __future__ import annotations

import numpy as np
import torch

from pchc_rsl.evaluation.progress import Progress


def run_episodes(env, policy, preference, episodes: int, progress: str = "") -> tuple[list[dict], np.ndarray]:
    """Roll the deterministic policy until every env finished ``episodes`` episodes at ``preference``.

    Returns one metric dict per finished episode and the mean per-step reward groups [T, 1 + m] of the first
    episode round (for step-wise curves)."""
    return run_preference_batch(env, policy, [preference], episodes, progress)[0]


def run_preference_batch(env, policy, preferences, episodes: int, progress: str = "") -> list[tuple[list[dict],
                                                                                                np.ndarray]]:
    """Every preference at once: the envs split into len(preferences) equal blocks, block k holding preferences[k]
    (lambda is per env), rolled until every env finished ``episodes`` episodes. One batch of P x n envs steps the
    physics as much as P runs of n envs, with a P-th of the steps' fixed costs.

    Returns, per preference, its finished episodes' metric dicts and its envs' mean per-step reward groups
    [T, 1 + m] over the first episode round."""
    count = len(preferences)
    if env.num_envs % count:
        raise ValueError(f"{env.num_envs} envs cannot be split evenly among {count} preferences.")
    block = env.num_envs // count
    owner = torch.arange(env.num_envs) // block  # [N] the preference index of each env
    finished = torch.zeros(env.num_envs, dtype=torch.long)
    results: list[list[dict]] = [[] for _ in preferences]
    curves: list[list[np.ndarray]] = [[] for _ in preferences]
    steps = 0
    meter = Progress(progress, episodes * env.max_episode_length) if progress else None
    lam = torch.tensor([list(p) for p in preferences], dtype=torch.float32).repeat_interleave(block, 0)
    with torch.inference_mode():  # the env's buffers are inference tensors once stepped in this mode
        env.set_preference(lam if count > 1 else preferences[0])
        env.reset()
        obs = env.get_observations()
        while (finished < episodes).any():
            obs, _, _, extras = env.step(policy(obs))
            if steps < env.max_episode_length:
                means = extras["reward_groups"].reshape(count, block, -1).mean(1).numpy()
                for k in range(count):
                    curves[k].append(means[k])
            steps += 1
            done = extras["episode_metrics"]
            for row, env_id in enumerate(done["env_ids"].tolist()):
                if finished[env_id] < episodes:
                    results[int(owner[env_id])].append({k: float(v[row]) for k, v in done.items() if k != "env_ids"})
                    finished[env_id] += 1
            if meter is not None and steps % 10 == 0:
                meter.update(steps)
    if meter is not None:
        meter.finish()
    return [(results[k], np.array(curves[k])) for k in range(count)]


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
        Progress(progress, 1).finish()
    return results, np.array(curve)


def steady_walk(env, policy, preference, command, settle_s: float, measure_s: float):
    """Hold one preference and one command (vx, vy, wz) from a reset for settle_s + measure_s, acting with
    ``policy``. Yields once after the reset and once after every step: (observations, whether that step lies in the
    measured stretch after settle_s), so that a tool measures a walker once it got going, not its start-up."""
    steps, settle = round((settle_s + measure_s) / env.dt), round(settle_s / env.dt)
    command = torch.as_tensor(command, dtype=torch.float32)
    with torch.inference_mode():
        env.set_preference(preference)
        env.reset()
        obs = env.get_observations()
        yield obs, False
        for k in range(steps):
            env.commands[:] = command
            obs, _, _, _ = env.step(policy(obs))
            yield obs, k >= settle


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

