"""An rsl-rl VecEnv over N copies of any MO-Gymnasium environment, following the pchc-rsl env contract.

It lets PCHC run on environments nobody here wrote (the check in tools/studies/mo_benchmark.py). The vector reward
becomes the objective groups of ``extras["reward_groups"]``; the task group is zero unless ``task_reward_weights`` says
how to build it from the vector reward. Stepping loops over the copies in Python: MO-Gymnasium envs are single-instance
Gymnasium envs, and its own vector wrapper resets one step late (Gymnasium's NEXT_STEP mode), which would put a
zero-reward transition into every rollout.

Needs the optional extra: ``pip install -e ".[mo-gym]"``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch
from tensordict import TensorDict

from rsl_rl.env import VecEnv

from pchc_rsl.preference import EnvPreferences


@dataclass
class MOGymEnvConfig:
    env_id: str = "mo-hopper-2obj-v5"
    objective_names: list[str] = field(default_factory=lambda: ["forward", "height"])
    """One name per entry of the env's vector reward (logging and ``--fixed-preference`` length)."""
    task_reward_weights: list[float] | None = None
    """Task reward = these weights . vector reward (a preference-invariant part); None: no task reward (zero)."""
    history_length: int = 0
    """Past observations stacked into the policy group after the current one (0: the Markov observation alone)."""
    reward_scale: float = 1.0
    """Multiplies the rewards the critics learn from (values of order 1 train faster); logs stay in raw units.
    Each critic's advantage is normalised, so the policy update does not depend on it."""
    preference_concentration: float = 1.0
    make_kwargs: dict = field(default_factory=dict)
    """Extra keyword arguments for ``mo_gymnasium.make``."""


def make_mo_env(env_id: str, **kwargs):
    """``mo_gymnasium.make`` with an install hint when the optional extra is missing."""
    try:
        import mo_gymnasium
    except ImportError as error:
        raise ImportError(
            f"The MO-Gymnasium environments need the optional extra: pip install -e \".[mo-gym]\" ({error})."
        ) from error
    return mo_gymnasium.make(env_id, **kwargs)


class MOGymVecEnv(VecEnv):
    """N independent copies of an MO-Gymnasium env; actions are clipped to the action space, resets are immediate."""

    def __init__(self, cfg: MOGymEnvConfig, num_envs: int, device: str = "cpu", seed: int = 0) -> None:
        self.cfg = cfg
        self.num_envs = num_envs
        self.device = device
        self.envs = [make_mo_env(cfg.env_id, **cfg.make_kwargs) for _ in range(num_envs)]
        single = self.envs[0]
        reward_dim = single.unwrapped.reward_space.shape[0]
        if len(cfg.objective_names) != reward_dim:
            raise ValueError(f"{cfg.env_id} has {reward_dim} objectives but objective_names has "
                             f"{len(cfg.objective_names)}: {cfg.objective_names}.")
        if cfg.task_reward_weights is not None and len(cfg.task_reward_weights) != reward_dim:
            raise ValueError(f"task_reward_weights needs {reward_dim} entries, got {cfg.task_reward_weights}.")
        from gymnasium.spaces import Box  # importable once make_mo_env succeeded

        if not isinstance(single.action_space, Box):
            raise ValueError(f"{cfg.env_id} has a {type(single.action_space).__name__} action space; PCHC's Gaussian "
                             "policies need a continuous (Box) one.")
        self.num_objectives = reward_dim
        self.num_actions = single.action_space.shape[0]
        self.max_episode_length = single.spec.max_episode_steps or 1000
        self.action_low = torch.as_tensor(single.action_space.low, dtype=torch.float32)
        self.action_high = torch.as_tensor(single.action_space.high, dtype=torch.float32)
        self.task_weights = (None if cfg.task_reward_weights is None
                             else torch.tensor(cfg.task_reward_weights, dtype=torch.float32))
        self.generator = torch.Generator().manual_seed(seed)
        obs_dim = single.observation_space.shape[0]
        self.frames = torch.zeros(num_envs, cfg.history_length + 1, obs_dim)  # newest first
        self.episode_length_buf = torch.zeros(num_envs, dtype=torch.long)
        self.episode_sums = torch.zeros(num_envs, 1 + reward_dim)
        self.preferences = EnvPreferences(num_envs, reward_dim, cfg.preference_concentration, self.generator)
        self.preference = self.preferences.values
        for i, env in enumerate(self.envs):
            env.action_space.seed(seed + i)
            self._reset_env(i, seed=seed + i)

    def set_preference(self, lam) -> None:
        """Hold lambda ([m] for all envs, or [N, m]) from now on, also across resets; ``None`` resumes sampling."""
        self.preferences.hold(lam)

    def _reset_env(self, i: int, seed: int | None = None) -> None:
        obs, _ = self.envs[i].reset(seed=seed)
        self.frames[i] = torch.as_tensor(obs, dtype=torch.float32)  # history starts as copies of the first frame
        self.episode_length_buf[i] = 0
        self.episode_sums[i] = 0.0
        self.preferences.resample([i])

    def get_observations(self) -> TensorDict:
        return TensorDict(
            {
                "policy": self.frames.flatten(1).clone(),
                "preference": self.preference.clone(),
                "critic": self.frames[:, 0].clone(),
            },
            batch_size=[self.num_envs],
        ).to(self.device)

    def step(self, actions: torch.Tensor) -> tuple[TensorDict, torch.Tensor, torch.Tensor, dict]:
        actions = torch.clamp(actions.detach().cpu().float(), self.action_low, self.action_high).numpy()
        vector_rewards = np.zeros((self.num_envs, self.num_objectives), dtype=np.float32)
        terminated = np.zeros(self.num_envs, dtype=bool)
        truncated = np.zeros(self.num_envs, dtype=bool)
        next_obs = []
        for i, env in enumerate(self.envs):
            obs, vector_rewards[i], terminated[i], truncated[i], _ = env.step(actions[i])
            next_obs.append(obs)
        objectives = torch.from_numpy(vector_rewards)
        task = (torch.zeros(self.num_envs, 1) if self.task_weights is None
                else (objectives * self.task_weights).sum(-1, keepdim=True))
        reward_groups = torch.cat([task, objectives], dim=-1)
        reward = self.cfg.reward_scale * (task.squeeze(1) + (self.preference * objectives).sum(-1))

        self.frames[:, 1:] = self.frames[:, :-1].clone()
        self.frames[:, 0] = torch.as_tensor(np.stack(next_obs), dtype=torch.float32)
        self.episode_length_buf += 1
        self.episode_sums += reward_groups
        reward_groups = self.cfg.reward_scale * reward_groups
        dones = torch.from_numpy(terminated | truncated)
        time_outs = torch.from_numpy(truncated & ~terminated)

        log = {}
        done_ids = dones.nonzero(as_tuple=False).squeeze(-1).tolist()
        if done_ids:
            sums = self.episode_sums[done_ids]
            if self.task_weights is not None:
                log["Episode_Reward/task"] = sums[:, 0].mean()
            for k, name in enumerate(self.cfg.objective_names):
                log[f"Episode_Objective/{name}"] = sums[:, 1 + k].mean()
            log["Episode/length"] = self.episode_length_buf[done_ids].float().mean()
        for i in done_ids:
            self._reset_env(i)
        extras = {"time_outs": time_outs.to(self.device), "reward_groups": reward_groups.to(self.device), "log": log}
        return self.get_observations(), reward.to(self.device), dones.to(self.device), extras

    def close(self) -> None:
        for env in self.envs:
            env.close()
