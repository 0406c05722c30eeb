"""PCHC learns a preference-conditioned policy on the toy task: one policy, steered by lambda."""

import torch

from pchc_rsl.configs import task_config
from pchc_rsl.training.build import make_runner

PREFERENCES = [(1.0, 0.0), (0.75, 0.25), (0.5, 0.5), (0.25, 0.75), (0.0, 1.0)]


def evaluate(runner, preference):
    """Deterministic episode at a fixed preference: objective sums [m] and the mean position over its 2nd half."""
    env = runner.env
    policy = runner.get_inference_policy()
    env.set_preference(preference)
    env.reset()
    obs = env.get_observations()
    sums = torch.zeros(env.num_objectives)
    positions = []
    with torch.no_grad():
        for _ in range(env.max_episode_length):
            obs, _, _, extras = env.step(policy(obs))
            sums += extras["reward_groups"][:, 1:].mean(0)
            positions.append(env.pos.mean(0))
    return sums, torch.stack(positions[len(positions) // 2 :]).mean(0)


def test_pchc_follows_the_preference_on_the_toy_task():
    cfg = task_config("toy")
    cfg.seed = 0
    runner = make_runner(cfg)
    runner.learn(cfg.runner.max_iterations)
    goal_a, goal_b = runner.env.goals
    results = [evaluate(runner, lam) for lam in PREFERENCES]

    _, at_a = results[0]
    _, at_b = results[-1]
    assert (at_a - goal_a).norm() < 0.5 * (at_a - goal_b).norm(), f"lambda=(1,0) ends at {at_a.tolist()}"
    assert (at_b - goal_b).norm() < 0.5 * (at_b - goal_a).norm(), f"lambda=(0,1) ends at {at_b.tolist()}"
    objective_a = [s[0].item() for s, _ in results]
    objective_b = [s[1].item() for s, _ in results]
    # Moving lambda from objective A to B trades A for B, monotonically
    assert all(x > y for x, y in zip(objective_a, objective_a[1:])), objective_a
    assert all(x < y for x, y in zip(objective_b, objective_b[1:])), objective_b
