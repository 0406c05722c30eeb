"""Per-episode sums of step quantities, turned into the paper's metrics when an episode ends."""

from __future__ import annotations

import torch


class EpisodeSums:
    """Running sums per env of named per-step quantities; reading them has no side effect."""

    def __init__(self, num_envs: int, device: str = "cpu") -> None:
        self.num_envs, self.device = num_envs, device
        self.sums: dict[str, torch.Tensor] = {}

    def add(self, values: dict[str, torch.Tensor]) -> None:
        for key, value in values.items():
            if key not in self.sums:  # [N] or [N, ...] (a histogram per env)
                self.sums[key] = torch.zeros_like(value, device=self.device)
            self.sums[key] += value

    def get(self, env_ids: torch.Tensor) -> dict[str, torch.Tensor]:
        return {k: v[env_ids] for k, v in self.sums.items()}

    def reset(self, env_ids: torch.Tensor) -> None:
        for value in self.sums.values():
            value[env_ids] = 0.0


def ratio(total: torch.Tensor, count: torch.Tensor) -> torch.Tensor:
    """total / count, NaN where count is 0 (a metric undefined in that episode)."""
    return torch.where(count > 0, total / count.clamp(min=1), float("nan"))


def larger_over_smaller(pair: torch.Tensor) -> torch.Tensor:
    """[n, 2] left and right figures -> [n] the larger over the smaller (1: symmetric); NaN where either is NaN or
    not positive (a foot that never stepped forward has no ratio)."""
    low, high = pair.min(dim=-1).values, pair.max(dim=-1).values
    return torch.where(low > 0, high / low.clamp(min=1e-9), float("nan"))
