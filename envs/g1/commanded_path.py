"""The path a commanded twist (forward, sideways, yaw rate) takes a body along, integrated exactly per step.

Both the reference of the disturbance objective (envs/g1/pushes.py) and the walker's position hold follow it: a
robot that does as told stays on it, turning included.
"""

from __future__ import annotations

import math

import torch


def rotate(xy: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
    """[N, 2] vectors turned by ``yaw`` [N] (rad) about the vertical: body frame -> world frame."""
    c, s = yaw.cos(), yaw.sin()
    return torch.stack([c * xy[:, 0] - s * xy[:, 1], s * xy[:, 0] + c * xy[:, 1]], dim=-1)


def arc_step(velocity: torch.Tensor, turn: torch.Tensor, dt: float) -> torch.Tensor:
    """[N, 2] displacement, in the frame the body had at the step's start, of a body that moves at ``velocity``
    [N, (v_x, v_y)] in its own frame while turning by ``turn`` [N] (rad) over ``dt``.

    Exact for a twist held over the step: (v_x sin(w dt) - v_y (1 - cos(w dt)), v_x (1 - cos(w dt)) + v_y sin(w dt))
    / w, and (v_x dt, v_y dt) as w -> 0 (sinc keeps that limit free of division by zero)."""
    sin_over_w = dt * torch.sinc(turn / math.pi)  # sin(w dt) / w
    one_minus_cos_over_w = dt * torch.sin(turn / 2) * torch.sinc(turn / (2 * math.pi))  # (1 - cos(w dt)) / w
    return torch.stack([velocity[:, 0] * sin_over_w - velocity[:, 1] * one_minus_cos_over_w,
                        velocity[:, 0] * one_minus_cos_over_w + velocity[:, 1] * sin_over_w], dim=-1)


class CommandedPath:
    """Per env, the pose (x, y, yaw) its commands integrate to since the path was last restarted.

    Why: a kernel on the velocity barely sees a bias of a few cm/s under the sway of every step, but the bias adds
    up to where the robot ends; the distance from this path is what an operator who steers it sees.
    """

    def __init__(self, num_envs: int, dt: float, device: torch.device | str) -> None:
        self.dt = dt
        self.position = torch.zeros(num_envs, 2, device=device)
        self.yaw = torch.zeros(num_envs, device=device)

    def restart(self, where: torch.Tensor, position: torch.Tensor, yaw: torch.Tensor) -> None:
        """Start the path again at the robot's pose ([N, 2] world position, [N] yaw) where ``where`` [N] is true
        (a mask, not indices: a GPU env finds no indices without waiting on the device)."""
        self.position = torch.where(where.unsqueeze(-1), position, self.position)
        self.yaw = torch.where(where, yaw, self.yaw)

    def advance(self, commands: torch.Tensor) -> None:
        """Move along the path by one step of the twist [N, (forward, sideways, yaw rate)]."""
        turn = commands[:, 2] * self.dt
        self.position = self.position + rotate(arc_step(commands[:, :2], turn, self.dt), self.yaw)
        self.yaw = self.yaw + turn

    def error(self, position: torch.Tensor) -> torch.Tensor:
        """[N, 2] the robot's world position minus the path's."""
        return position - self.position
