"""RolloutStorage with K reward groups: rewards, values and returns are [T, N, K]; advantages stay [T, N, 1]."""

from __future__ import annotations

import torch
from tensordict import TensorDict

from rsl_rl.storage import RolloutStorage


class MultiCriticRolloutStorage(RolloutStorage):
    """rsl-rl's storage widened to K critics (task + one per objective).

    The mini-batch generators flatten whatever trailing width the buffers have, so only the allocation and the
    reward copy (which rsl-rl reshapes to one column) change.
    """

    def __init__(
        self,
        num_envs: int,
        num_transitions_per_env: int,
        obs: TensorDict,
        actions_shape: tuple[int, ...] | list[int],
        num_critics: int,
        device: str = "cpu",
    ) -> None:
        super().__init__("rl", num_envs, num_transitions_per_env, obs, actions_shape, device)
        self.num_critics = num_critics
        shape = (num_transitions_per_env, num_envs, num_critics)
        self.rewards = torch.zeros(*shape, device=self.device)
        self.values = torch.zeros(*shape, device=self.device)
        self.returns = torch.zeros(*shape, device=self.device)

    def add_transition(self, transition: RolloutStorage.Transition) -> None:
        """Store a transition whose rewards are the [N, K] reward groups."""
        step = self.step
        reward_groups = transition.rewards
        transition.rewards = reward_groups[:, 0]  # the base class copies a single column; overwrite below
        super().add_transition(transition)
        self.rewards[step].copy_(reward_groups)
