"""Each env's first episode at one preference: its summed reward groups, whether it fell, and how long it lasted.

The reward groups are what MultiCriticPPO optimises (the task group, then one per objective), so their returns tell
how far training has got at each preference apart from how well a reward stands in for a physical metric.
"""

from __future__ import annotations

import torch

from pchc_rsl.evaluation.checkpoint import evaluation_config, loaded_policy, task_config_of


def policy_under_pushes(checkpoint: str, pushes: str, num_envs: int, tool: str):
    """A G1 checkpoint's (config, runner, policy) under the task's evaluation preset, pushed as the preset ``pushes``
    names or not at all ("off"). A preset the task lacks stops ``tool`` with one line naming --pushes."""
    config = task_config_of(checkpoint, "g1-", tool, "a G1 task")
    try:
        cfg = evaluation_config(config, "mild" if pushes == "off" else pushes, num_envs, seed=0)
    except ValueError as error:
        raise SystemExit(f"{tool}: --pushes: {error}") from None
    cfg.env.push.enabled = pushes != "off"
    runner, policy = loaded_policy(checkpoint, cfg)
    return cfg, runner, policy


def first_episode_returns(env, policy, preference) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """[N, groups] each env's first episode's summed reward groups (task first, then the objectives), [N] bool
    whether that episode ended in a fall, and [N] its length in policy steps."""
    shape = (env.num_envs, 1 + env.num_objectives)
    sums, returns = torch.zeros(shape), torch.zeros(shape)
    steps, lengths = torch.zeros(env.num_envs, dtype=torch.long), torch.zeros(env.num_envs, dtype=torch.long)
    finished = torch.zeros(env.num_envs, dtype=torch.bool)
    fell = torch.zeros(env.num_envs, dtype=torch.bool)
    with torch.inference_mode():
        env.set_preference(preference)
        env.reset()
        obs = env.get_observations()
        while not finished.all():
            obs, _, dones, extras = env.step(policy(obs))
            sums += extras["reward_groups"].cpu()
            steps += 1
            ended = dones.cpu().bool()
            first = ended & ~finished
            returns[first] = sums[first]
            lengths[first] = steps[first]
            done = extras["episode_metrics"]
            fell_now = torch.zeros_like(ended)
            fell_now[done["env_ids"].cpu()] = done["fell"].cpu().bool()
            fell |= first & fell_now
            finished |= ended
            sums[ended] = 0.0
            steps[ended] = 0
    return returns, fell, lengths
