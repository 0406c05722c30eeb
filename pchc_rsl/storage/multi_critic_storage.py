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

    def mini_batch_generator(self, num_mini_batches: int, num_epochs: int = 8):
        """rsl-rl's generator (the same permutation, the same batches in the same order) gathering the rows with
        ``index_select``, which is faster than advanced indexing on a CPU (tools/benchmarks/bench_update.py times the
        two)."""
        if self.training_type != "rl":
            raise ValueError("This function is only available for reinforcement learning training.")
        batch_size = self.num_envs * self.num_transitions_per_env
        mini_batch_size = batch_size // num_mini_batches
        indices = torch.randperm(num_mini_batches * mini_batch_size, requires_grad=False, device=self.device)
        observations = self.observations.flatten(0, 1)
        flat = [t.flatten(0, 1) for t in (self.actions, self.values, self.advantages, self.returns,
                                         self.actions_log_prob)]
        old_distribution_params = tuple(p.flatten(0, 1) for p in self.distribution_params)  # type: ignore
        for _ in range(num_epochs):
            for i in range(num_mini_batches):
                rows = indices[i * mini_batch_size : (i + 1) * mini_batch_size]
                actions, values, advantages, returns, log_prob = (t.index_select(0, rows) for t in flat)
                yield RolloutStorage.Batch(
                    observations=TensorDict({k: v.index_select(0, rows) for k, v in observations.items()},
                                            batch_size=[rows.shape[0]], device=observations.device),
                    actions=actions,
                    values=values,
                    advantages=advantages,
                    returns=returns,
                    old_actions_log_prob=log_prob,
                    old_distribution_params=tuple(p.index_select(0, rows) for p in old_distribution_params),
                )
