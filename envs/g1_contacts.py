"""Foot contacts, touchdowns, air time and the paper's stride length, from the substep sole forces."""

from __future__ import annotations

import torch


class FootContacts:
    """Per-env contact state of the two feet. ``stride``: at each touchdown this step, the horizontal distance
    from where that foot last touched the ground (0 elsewhere), m."""

    def __init__(self, num_envs: int, dt: float, force_threshold: float, device: str = "cpu") -> None:
        self.dt, self.force_threshold = dt, force_threshold
        self.contact = torch.zeros(num_envs, 2, dtype=torch.bool, device=device)
        self.first_contact = torch.zeros(num_envs, 2, dtype=torch.bool, device=device)
        self.air_time = torch.zeros(num_envs, 2, device=device)
        self.last_air_time = torch.zeros(num_envs, 2, device=device)
        self.last_contact_pos = torch.zeros(num_envs, 2, 2, device=device)
        self.stride = torch.zeros(num_envs, 2, device=device)

    def in_contact(self, touch_substeps: torch.Tensor) -> torch.Tensor:
        """[N, K, 2] sole forces -> [N, 2]: in contact at any substep."""
        return (touch_substeps > self.force_threshold).any(dim=1)

    def update(self, touch_substeps: torch.Tensor, foot_pos: torch.Tensor) -> None:
        """Touchdowns this step; the touchdown point becomes the foot's new last contact point."""
        contact = self.in_contact(touch_substeps)
        self.first_contact = contact & ~self.contact
        foot_xy = foot_pos[..., :2]
        self.stride = torch.where(self.first_contact, (foot_xy - self.last_contact_pos).norm(dim=-1), 0.0)
        self.last_air_time = torch.where(self.first_contact, self.air_time + self.dt, self.last_air_time)
        self.air_time = torch.where(contact, 0.0, self.air_time + self.dt)
        self.last_contact_pos = torch.where(contact.unsqueeze(-1), foot_xy, self.last_contact_pos)
        self.contact = contact

    def reset(self, env_ids: torch.Tensor, touch_substeps: torch.Tensor, foot_pos: torch.Tensor,
              planted_height: float) -> None:
        """Start from the reset state itself (a forward pass of it): a foot touching the ground or within
        ``planted_height`` of it is in contact, so settling onto it is not a touchdown."""
        planted = foot_pos[env_ids, :, 2] < planted_height
        self.contact[env_ids] = self.in_contact(touch_substeps[env_ids]) | planted
        self.first_contact[env_ids] = False
        self.stride[env_ids] = 0.0
        self.air_time[env_ids] = 0.0
        self.last_air_time[env_ids] = 0.0
        self.last_contact_pos[env_ids] = foot_pos[env_ids, :, :2]
