"""MultiCriticPPO and the PCI actor in rsl-rl's own OnPolicyRunner, configured as the README says.

The env is written here from scratch, as a user of another rsl-rl project would: two goals, the objectives are the
negative squared distances to them, and the task reward group is all zeros. With default algorithm settings the
policy must go to goal A under lambda = (1, 0) and to goal B under (0, 1).
"""

import torch
from tensordict import TensorDict

from rsl_rl.env import VecEnv
from rsl_rl.runners import OnPolicyRunner

GOALS = torch.tensor([[1.0, 0.0], [0.0, 1.0]])


class TwoGoalEnv(VecEnv):
    def __init__(self, num_envs: int, episode_length: int = 16, seed: int = 0) -> None:
        self.num_envs, self.num_actions, self.max_episode_length = num_envs, 2, episode_length
        self.device, self.cfg = "cpu", {}
        self.gen = torch.Generator().manual_seed(seed)
        self.pos = torch.zeros(num_envs, 2)
        self.lam = torch.zeros(num_envs, 2)
        self.episode_length_buf = torch.zeros(num_envs, dtype=torch.long)
        self.fixed = None
        self.reset(torch.arange(num_envs))

    def reset(self, ids: torch.Tensor) -> None:
        self.pos[ids] = 0.0
        self.episode_length_buf[ids] = 0
        if self.fixed is not None:
            self.lam[ids] = self.fixed
        else:
            self.lam[ids] = torch.distributions.Dirichlet(torch.ones(2)).sample((len(ids),))

    def get_observations(self) -> TensorDict:
        t = self.episode_length_buf.float().unsqueeze(1) / self.max_episode_length
        state = torch.cat([self.pos, t], dim=-1)
        return TensorDict({"policy": state.clone(), "critic": state.clone(), "preference": self.lam.clone()},
                          batch_size=[self.num_envs])

    def step(self, actions: torch.Tensor):
        self.pos += 0.15 * actions.clamp(-1.0, 1.0)
        self.episode_length_buf += 1
        objectives = -((self.pos.unsqueeze(1) - GOALS) ** 2).sum(-1)  # [N, 2]
        groups = torch.cat([torch.zeros(self.num_envs, 1), objectives], dim=-1)
        time_outs = self.episode_length_buf >= self.max_episode_length
        extras = {"reward_groups": groups, "time_outs": time_outs.clone(), "log": {}}
        rewards = (self.lam * objectives).sum(-1)
        self.reset(time_outs.nonzero().squeeze(-1))
        return self.get_observations(), rewards, time_outs.clone(), extras


TRAIN_CFG = {
    "num_steps_per_env": 16,
    "save_interval": 1000,
    "obs_groups": {"actor": ["policy", "preference"], "critic": ["critic", "preference"]},
    "algorithm": {"class_name": "pchc_rsl.algorithms:MultiCriticPPO", "learning_rate": 3e-3, "gamma": 0.95},
    "actor": {"class_name": "pchc_rsl.modules:PCIActor", "hidden_dims": [64, 64], "history_length": 0,
              "distribution_cfg": {"class_name": "rsl_rl.modules:GaussianDistribution", "init_std": 0.3}},
    "critic": {"class_name": "pchc_rsl.modules:PreferenceMLPModel", "hidden_dims": [64, 64]},
    "logger": "tensorboard",
}


def final_position(runner, env, lam) -> torch.Tensor:
    env.fixed = torch.tensor(lam)
    env.reset(torch.arange(env.num_envs))
    policy = runner.get_inference_policy()
    obs = env.get_observations()
    with torch.inference_mode():
        for _ in range(env.max_episode_length - 1):
            obs, *_ = env.step(policy(obs))
    return env.pos.mean(0)


def test_zero_task_group_with_default_settings_reaches_each_goal_through_rsl_rl_runner():
    torch.manual_seed(0)
    env = TwoGoalEnv(64)
    runner = OnPolicyRunner(env, {k: (dict(v) if isinstance(v, dict) else v) for k, v in TRAIN_CFG.items()},
                            log_dir=None, device="cpu")
    runner.learn(80)
    at_a = final_position(runner, env, [1.0, 0.0])
    at_b = final_position(runner, env, [0.0, 1.0])
    assert (at_a - GOALS[0]).norm() < 0.35, f"lambda = (1, 0) ends at {at_a.tolist()}, goal A is (1, 0)"
    assert (at_b - GOALS[1]).norm() < 0.35, f"lambda = (0, 1) ends at {at_b.tolist()}, goal B is (0, 1)"
