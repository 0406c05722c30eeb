"""The latency from a new action to the actuators, as a robot has it: drawn per episode, in physics substeps, during
which the actuators still hold the previous target."""

from __future__ import annotations

import torch


class ActionDelay:
    """Each env's delay, in substeps of a policy step of ``decimation`` substeps; ``delay_s`` (low, high) in seconds."""

    def __init__(self, delay_s: tuple[float, float], timestep: float, decimation: int, num_envs: int,
                 generator: torch.Generator) -> None:
        self.low, self.high = (int(round(t / timestep)) for t in delay_s)
        if not 0 <= self.low <= self.high <= decimation:
            raise ValueError(f"action_delay_s {tuple(delay_s)} must be 0 <= low <= high <= one policy step "
                             f"({timestep * decimation:g} s).")
        self.decimation, self.generator = decimation, generator
        self.substeps = torch.zeros(num_envs, dtype=torch.long, device=generator.device)
        """[N] each env's delay in physics substeps (see G1EnvConfig.action_delay_s)."""

    def reset(self, env_ids: torch.Tensor) -> None:
        """Draw these envs' delays for their new episodes."""
        self.substeps[env_ids] = torch.randint(self.low, self.high + 1, (len(env_ids),), generator=self.generator,
                                               device=self.generator.device)

    def control(self, target: torch.Tensor, previous: torch.Tensor) -> torch.Tensor:
        """[N, J] this step's target -> the control the physics holds: [N, J] without delay, else [N, K, J] with the
        ``previous`` target for each env's first ``substeps``."""
        if self.high == 0:
            return target
        substep = torch.arange(self.decimation, device=target.device)
        held = (substep.unsqueeze(0) < self.substeps.unsqueeze(1)).unsqueeze(-1)  # [N, K, 1]
        return torch.where(held, previous.unsqueeze(1), target.unsqueeze(1))
