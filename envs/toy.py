"""A two-objective point-mass task in pure torch: a fast end-to-end check of PCHC (the ``toy`` task).

A point starts near the origin and moves with velocity actions. Objective 1 rewards being close to goal A,
objective 2 being close to goal B (negative squared distances), so under preference lambda the best place to be is
lambda_1 A + lambda_2 B: the Pareto front is the segment between the goals.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
from tensordict import TensorDict

from rsl_rl.env import VecEnv

from pchc_rsl.preference import EnvPreferences


@dataclass
class ToyEnvConfig:
    goal_a: tuple[float, float] = (1.0, 0.0)
    goal_b: tuple[float, float] = (0.0, 1.0)
    episode_length: int = 20
    step_size: float = 0.15
    """Distance moved per step at full action."""
    action_cost: float = 0.01
    """Task (preference-invariant) penalty on the squared action."""
    history_length: int = 5
    """Past frames stacked into the policy observation after the current one."""
    preference_concentration: float = 1.0
    objective_names: list[str] = field(default_factory=lambda: ["goal_a", "goal_b"])


class ToyEnv(VecEnv):
    """Vectorised point-mass with two conflicting goals; follows the pchc-rsl env contract (DESIGN.md)."""

    def __init__(self, cfg: ToyEnvConfig, num_envs: int, device: str = "cpu", seed: int = 0) -> None:
        self.cfg = cfg
        self.num_envs = num_envs
        self.num_actions = 2
        self.num_objectives = 2
        self.device = device
        self.max_episode_length = cfg.episode_length
        self.generator = torch.Generator(device=device).manual_seed(seed)
        self.goals = torch.tensor([cfg.goal_a, cfg.goal_b], device=device)  # [m, 2]
        self.pos = torch.zeros(num_envs, 2, device=device)
        self.frames = torch.zeros(num_envs, cfg.history_length + 1, 4, device=device)  # newest first
        self.episode_length_buf = torch.zeros(num_envs, dtype=torch.long, device=device)
        self.episode_sums = torch.zeros(num_envs, 1 + self.num_objectives, device=device)
        self.preferences = EnvPreferences(num_envs, self.num_objectives, cfg.preference_concentration, self.generator,
                                          device)
        self.preference = self.preferences.values
        self.reset()

    def set_preference(self, lam) -> None:
        """Hold lambda ([m] for all envs, or [N, m]) from now on, also across resets; ``None`` resumes sampling."""
        self.preferences.hold(lam)

    def reset(self, env_ids: torch.Tensor | None = None) -> None:
        """Start new episodes in these envs (all by default)."""
        if env_ids is None:
            env_ids = torch.arange(self.num_envs, device=self.device)
        n = len(env_ids)
        if n == 0:
            return
        self.pos[env_ids] = 0.1 * (2 * torch.rand(n, 2, generator=self.generator, device=self.device) - 1)
        self.frames[env_ids] = 0.0
        self.frames[env_ids, :, :2] = self.pos[env_ids].unsqueeze(1)
        self.episode_length_buf[env_ids] = 0
        self.episode_sums[env_ids] = 0.0
        self.preferences.resample(env_ids)

    def state_dict(self) -> dict:
        """Everything that evolves: a resumed run continues exactly where the checkpoint was written."""
        return {"generator": self.generator.get_state(), "pos": self.pos.clone(), "frames": self.frames.clone(),
                "episode_length_buf": self.episode_length_buf.clone(), "episode_sums": self.episode_sums.clone(),
                "preference": self.preference.clone()}

    def load_state_dict(self, state: dict) -> None:
        """Restore the generator, and the per-env state when the env count is the same (a resume may change it:
        the new envs then start fresh episodes)."""
        self.generator.set_state(state["generator"])
        if state["pos"].shape[0] != self.num_envs:
            return
        for key in ("pos", "frames", "episode_length_buf", "episode_sums", "preference"):
            getattr(self, key).copy_(state[key])

    def get_observations(self) -> TensorDict:
        time_left = 1.0 - self.episode_length_buf.float().unsqueeze(1) / self.max_episode_length
        return TensorDict(
            {
                "policy": self.frames.flatten(1).clone(),  # never alias buffers that step() updates in place
                "preference": self.preference.clone(),
                "critic": torch.cat([self.pos, time_left], dim=-1),
            },
            batch_size=[self.num_envs],
            device=self.device,
        )

    def objective_rewards(self) -> torch.Tensor:
        """[N, m]: -||p - g_i||^2 for each goal."""
        return -((self.pos.unsqueeze(1) - self.goals.unsqueeze(0)) ** 2).sum(-1)

    def step(self, actions: torch.Tensor) -> tuple[TensorDict, torch.Tensor, torch.Tensor, dict]:
        actions = actions.clamp(-1.0, 1.0)
        self.pos += self.cfg.step_size * actions
        self.frames[:, 1:] = self.frames[:, :-1].clone()  # in place: buffers stay usable outside inference mode
        self.frames[:, 0] = torch.cat([self.pos, actions], dim=-1)
        self.episode_length_buf += 1

        task = -self.cfg.action_cost * (actions**2).sum(-1, keepdim=True)
        objectives = self.objective_rewards()
        reward_groups = torch.cat([task, objectives], dim=-1)  # [N, 1 + m], objectives raw
        reward = task.squeeze(1) + (self.preference * objectives).sum(-1)
        self.episode_sums += reward_groups

        time_outs = self.episode_length_buf >= self.max_episode_length
        done_ids = time_outs.nonzero(as_tuple=False).squeeze(-1)
        log = {}
        if len(done_ids) > 0:
            sums = self.episode_sums[done_ids]
            log["Episode_Reward/task"] = sums[:, 0].mean()
            for i, name in enumerate(self.cfg.objective_names):
                log[f"Episode_Objective/{name}"] = sums[:, 1 + i].mean()
        extras = {"time_outs": time_outs.clone(), "reward_groups": reward_groups, "log": log}
        self.reset(done_ids)
        return self.get_observations(), reward, time_outs.clone(), extras
