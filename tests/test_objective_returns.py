"""first_episode_returns (behind tools/diagnostics/objective_returns.py) sums each env's first episode's reward
groups and counts its steps, whatever the episode lengths."""

import torch

from pchc_rsl.evaluation.group_returns import first_episode_returns


class ScriptedEnv:
    """Two envs, one objective: env 0's episodes last 3 steps and end in a fall, env 1's last 2 and time out; step t
    pays (t, 10 t) to every env."""

    num_envs, num_objectives = 2, 1

    def __init__(self):
        self.t, self.length = 0, torch.zeros(2, dtype=torch.long)

    def set_preference(self, lam):
        self.preference = lam

    def reset(self):
        self.t, self.length[:] = 0, 0

    def get_observations(self):
        return torch.zeros(2, 1)

    def step(self, actions):
        self.t += 1
        self.length += 1
        dones = self.length == torch.tensor([3, 2])
        self.length[dones] = 0
        groups = torch.tensor([[self.t, 10.0 * self.t]] * 2)
        ids = dones.nonzero().squeeze(-1)
        finished = {"env_ids": ids, "fell": ids == 0}
        return self.get_observations(), None, dones, {"reward_groups": groups, "episode_metrics": finished}


def test_first_episode_returns_match_a_hand_sum():
    returns, fell, lengths = first_episode_returns(ScriptedEnv(), lambda obs: obs, (1.0, 0.0))
    # env 0: steps 1-3; env 1: steps 1-2 (its second episode, steps 3-4, is not counted)
    torch.testing.assert_close(returns, torch.tensor([[6.0, 60.0], [3.0, 30.0]]))
    assert fell.tolist() == [True, False]
    assert lengths.tolist() == [3, 2]
