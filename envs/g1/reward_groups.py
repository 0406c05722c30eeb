"""Reward terms summed into the env contract's groups: the task group, then one per objective."""

from __future__ import annotations

import torch

from rsl_rl.utils import resolve_callable

from pchc_rsl.envs.g1.config import RewardTerm


class RewardGroups:
    """Each term contributes weight * term(env, **params) * dt per step to its group; [N, 1 + m] per step."""

    def __init__(self, terms: list[RewardTerm], objective_names: list[str], dt: float) -> None:
        self.names = ["task", *objective_names]
        self.index = {g: i for i, g in enumerate(self.names)}
        for term in terms:
            if term.group not in self.index:
                raise ValueError(f"Reward term {term.func} has group '{term.group}'; allowed: {self.names}.")
        self.terms = [(resolve_callable(t.func), t) for t in terms]
        self.dt = dt

    def term_pay(self, env) -> torch.Tensor:
        """[N, terms] each term's weight * value at the env's current state, per second
        (tools/diagnostics/reward_terms.py)."""
        return torch.stack([term.weight * func(env, **term.params) for func, term in self.terms], dim=-1)

    def compute(self, env) -> torch.Tensor:
        groups = torch.zeros(env.num_envs, len(self.names), device=env.device)
        pay = self.term_pay(env)
        for k, (_, term) in enumerate(self.terms):
            groups[:, self.index[term.group]] += pay[:, k] * self.dt
        return groups
