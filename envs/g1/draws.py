"""Random draws of a G1 env's parts, all from the env's one seeded generator (on the env's device)."""

from __future__ import annotations

import torch


def uniform(generator: torch.Generator, n: int, low: float, high: float) -> torch.Tensor:
    """[n] uniform in [low, high)."""
    return low + (high - low) * torch.rand(n, generator=generator, device=generator.device)


def chance(generator: torch.Generator, n: int, probability: float) -> torch.Tensor:
    """[n] bools, each True with ``probability``."""
    return torch.rand(n, generator=generator, device=generator.device) < probability
