"""Foot contacts, touchdowns, air time and step displacements, from the substep sole forces."""

from __future__ import annotations

import torch

MAX_AIR_STEPS = 50
"""Air-time histogram bins: 1 .. MAX_AIR_STEPS policy steps, the last bin also holding longer swings."""


class FootContacts:
    """Per-env contact state of the two feet.

    At a touchdown the foot's displacement from where it last touched the ground (its lift-off point) is its step,
    ``step_vector`` (forward along the base heading, lateral), and ``stride`` its length (0 where no foot touched
    down). ``stance_step`` holds a foot's step for as long as that stance lasts (0 in the air): the paper's
    I_contact ||p_current - p_last_contact|| read per step (see rewards.stride)."""

    def __init__(self, num_envs: int, dt: float, force_threshold: float, device: str = "cpu") -> None:
        self.dt, self.force_threshold = dt, force_threshold
        self.contact = torch.zeros(num_envs, 2, dtype=torch.bool, device=device)
        self.first_contact = torch.zeros(num_envs, 2, dtype=torch.bool, device=device)
        self.air_time = torch.zeros(num_envs, 2, device=device)
        self.last_air_time = torch.zeros(num_envs, 2, device=device)
        self.last_contact_pos = torch.zeros(num_envs, 2, 2, device=device)
        self.stride = torch.zeros(num_envs, 2, device=device)
        self.step_vector = torch.zeros(num_envs, 2, 2, device=device)
        """[N, foot, (forward, lateral)] this step's touchdown displacement in the heading frame (0: no touchdown)."""
        self.stance_step = torch.zeros(num_envs, 2, 2, device=device)
        """[N, foot, (forward, lateral)] the step that began the foot's current stance; 0 while in the air."""

    def in_contact(self, touch_substeps: torch.Tensor) -> torch.Tensor:
        """[N, K, 2] sole forces -> [N, 2]: in contact at any substep."""
        return (touch_substeps > self.force_threshold).any(dim=1)

    def update(self, touch_substeps: torch.Tensor, foot_pos: torch.Tensor, heading: torch.Tensor | None = None) -> None:
        """Touchdowns this step; the touchdown point becomes the foot's new last contact point. ``heading`` [N, 2]:
        the base's forward unit vector in the world (default +x), the frame of ``step_vector``."""
        contact = self.in_contact(touch_substeps)
        self.first_contact = contact & ~self.contact
        foot_xy = foot_pos[..., :2]
        displacement = foot_xy - self.last_contact_pos  # [N, 2, 2] world
        if heading is None:
            heading = torch.zeros_like(foot_xy[:, 0])
            heading[:, 0] = 1.0
        fx, fy = heading[:, None, 0], heading[:, None, 1]
        local = torch.stack([displacement[..., 0] * fx + displacement[..., 1] * fy,
                             -displacement[..., 0] * fy + displacement[..., 1] * fx], dim=-1)
        touched = self.first_contact.unsqueeze(-1)
        self.step_vector = torch.where(touched, local, 0.0)
        self.stride = torch.where(self.first_contact, displacement.norm(dim=-1), 0.0)
        self.stance_step = torch.where(touched, local, torch.where(contact.unsqueeze(-1), self.stance_step, 0.0))
        self.last_air_time = torch.where(self.first_contact, self.air_time + self.dt, self.last_air_time)
        self.air_time = torch.where(contact, 0.0, self.air_time + self.dt)
        self.last_contact_pos = torch.where(contact.unsqueeze(-1), foot_xy, self.last_contact_pos)
        self.contact = contact

    def air_time_histogram(self) -> torch.Tensor:
        """[N, 2, MAX_AIR_STEPS] this step's touchdowns of each foot counted by their air time in policy steps
        (bin b: b + 1 steps)."""
        steps = (self.last_air_time / self.dt).round().long().clamp(1, MAX_AIR_STEPS) - 1  # [N, 2]
        counts = torch.zeros(*self.contact.shape, MAX_AIR_STEPS, device=self.contact.device)
        return counts.scatter_add_(2, steps.unsqueeze(-1), self.first_contact.float().unsqueeze(-1))

    def reset(self, env_ids: torch.Tensor, touch_substeps: torch.Tensor, foot_pos: torch.Tensor,
              planted_height: float) -> None:
        """Start from the reset state itself (a forward pass of it): a foot touching the ground or within
        ``planted_height`` of it is in contact, so settling onto it is not a touchdown."""
        planted = foot_pos[env_ids, :, 2] < planted_height
        self.contact[env_ids] = self.in_contact(touch_substeps[env_ids]) | planted
        self.first_contact[env_ids] = False
        self.stride[env_ids] = 0.0
        self.step_vector[env_ids] = 0.0
        self.stance_step[env_ids] = 0.0
        self.air_time[env_ids] = 0.0
        self.last_air_time[env_ids] = 0.0
        self.last_contact_pos[env_ids] = foot_pos[env_ids, :, :2]


def median_from_histogram(counts: torch.Tensor, dt: float) -> torch.Tensor:
    """[..., B] touchdown counts per air-time bin -> [...] median air time, s (the lower median; NaN with no
    touchdown)."""
    total = counts.sum(-1)
    cumulative = counts.cumsum(-1)
    index = (cumulative < (total / 2).unsqueeze(-1)).sum(-1).clamp(max=counts.shape[-1] - 1)
    return torch.where(total > 0, (index + 1).float() * dt, float("nan"))
