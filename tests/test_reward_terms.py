"""tools/diagnostics/reward_terms.py: the per-term pay it reports adds up to the reward the env pays."""

import torch
from tool_loader import load_tool

reward_terms = load_tool("diagnostics/reward_terms")


class RecordingEnv:
    """A G1 walking env that keeps the reward each step returns."""

    def __init__(self, env):
        self.env, self.returned = env, []

    def __getattr__(self, name):
        return getattr(self.env, name)

    def step(self, actions):
        obs, reward, dones, extras = self.env.step(actions)
        self.returned.append(reward.clone())
        return obs, reward, dones, extras


def test_the_terms_of_each_weighted_group_add_up_to_the_reward_the_env_returns():
    """At lambda = (0.3, 0.7) the env returns task + 0.3 disturbance + 0.7 stride, each group the sum of its terms
    times dt; the tool's per-second pay, weighted the same way, times dt, must equal the mean of what the env
    returned over the measured steps (standing still with zero actions: no env falls or resets in 0.3 s)."""
    from pchc_rsl.configs import task_config
    from pchc_rsl.training.build import make_env

    cfg = task_config("g1-walk-fast")
    cfg.num_envs = 4
    env = RecordingEnv(make_env(cfg))
    preference = (0.3, 0.7)
    pay = reward_terms.mean_term_pay(env, lambda obs: torch.zeros(4, env.num_actions), preference, (0.5, 0.0, 0.0),
                                     settle_s=0.1, measure_s=0.2)
    weight = {"task": 1.0, "disturbance": preference[0], "stride": preference[1]}
    expected = sum(weight[term.group] * pay[i] for i, (_, term) in enumerate(env.rewards.terms)) * env.dt
    settle = round(0.1 / env.dt)
    returned = torch.stack(env.returned[settle:]).mean()
    assert abs(float(returned)) > 1e-3  # a reward to compare, not two zeros
    torch.testing.assert_close(torch.tensor(float(expected)), returned.float(), rtol=1e-4, atol=1e-6)
