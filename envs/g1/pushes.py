"""Pushes: horizontal velocity impulses on the pelvis, and what the paper measures after each.

After a push at position x_last with direction d, the 1 s window is the paper's "after-disturb" period. The
reference the robot should follow meanwhile starts at x_last with the robot's heading and moves as the commanded
twist (forward, sideways, yaw rate) moves a body: along an arc when a yaw rate is commanded, along the line
x_last + v_ref t when none is, and not at all without a command (the paper's equation). Deviation and the velocity
term of r_disturb are both taken relative to that reference, so turning as told inside a window costs nothing.
"""

from __future__ import annotations

import math

import torch

from pchc_rsl.envs.g1.commanded_path import arc_step, rotate
from pchc_rsl.envs.g1.config import PushConfig
from pchc_rsl.envs.g1.robot_state import RobotState, yaw_of


class Pushes:
    def __init__(self, cfg: PushConfig, num_envs: int, dt: float, generator: torch.Generator) -> None:
        self.cfg, self.dt, self.generator = cfg, dt, generator
        n, self.device = num_envs, generator.device
        self.countdown = torch.zeros(n, dtype=torch.long, device=self.device)
        """Policy steps until the next push."""
        self.window = torch.zeros(n, dtype=torch.long, device=self.device)
        """Policy steps left in the after-disturb window."""
        self.direction = torch.zeros(n, 2, device=self.device)
        self.origin = torch.zeros(n, 2, device=self.device)
        self.com_origin = torch.zeros(n, 2, device=self.device)
        self.origin_height = torch.zeros(n, device=self.device)
        self.ref_yaw = torch.zeros(n, device=self.device)
        """The reference's heading, rad, world frame: the robot's at the push, then turning at the commanded rate."""
        self.ref_offset = torch.zeros(n, 2, device=self.device)
        """How far the reference moved since the push, m, world frame."""
        self.ref_vel = torch.zeros(n, 2, device=self.device)
        """The reference's velocity now, m/s, world frame: the commanded velocity turned by ``ref_yaw``."""
        self.max_deviation = torch.zeros(n, device=self.device)
        """Largest base deviation from the reference in the current window, m."""
        self.max_com_deviation = torch.zeros(n, device=self.device)
        """Largest whole-body COM deviation from the reference in the current window, m."""
        self.next_speed = torch.full((n,), math.nan, device=self.device)
        self.next_angle = torch.full((n,), math.nan, device=self.device)
        """A requested push's speed (m/s) and direction (rad, world frame); NaN: drawn from the config."""

    def request(self, env_id: int, speed: float | None = None, angle: float | None = None) -> None:
        """Push env ``env_id`` at its next counting step (the web viewer's push button), at this speed and angle
        instead of drawn ones where given."""
        self.countdown[env_id] = 1
        self.next_speed[env_id] = math.nan if speed is None else speed
        self.next_angle[env_id] = math.nan if angle is None else angle

    def _uniform(self, n: int, low: float, high: float) -> torch.Tensor:
        return low + (high - low) * torch.rand(n, generator=self.generator, device=self.device)

    def _interval(self, n: int) -> torch.Tensor:
        return (self._uniform(n, *self.cfg.interval_s) / self.dt).long().clamp(min=1)

    def reset(self, env_ids: torch.Tensor) -> None:
        self.countdown[env_ids] = self._interval(len(env_ids))
        self.window[env_ids] = 0
        self.max_deviation[env_ids] = 0.0
        self.max_com_deviation[env_ids] = 0.0

    @property
    def window_steps(self) -> int:
        """Length of the window after a push, in policy steps."""
        return int(round(self.cfg.window_s / self.dt))

    @property
    def active(self) -> torch.Tensor:
        """[N] bool: inside the window after a push (the paper's I_after-disturb)."""
        return self.window > 0

    def apply(self, physics, robot: RobotState, commands: torch.Tensor,
              eligible: torch.Tensor | None = None) -> None:
        """Count down (only where ``eligible``), push the envs whose countdown ran out; record d, x_last, v_ref.

        Works on masks over all envs, never on the indices of the pushed ones: finding those would wait on the
        device at every step of a GPU env.
        """
        if not self.cfg.enabled:
            return
        counting = torch.ones_like(self.active) if eligible is None else eligible
        self.countdown -= counting.long()
        due = (self.countdown <= 0) & counting
        n = len(due)
        angle = torch.where(self.next_angle.isnan(), self._uniform(n, 0.0, 2 * math.pi), self.next_angle)
        speed = torch.where(self.next_speed.isnan(), self._uniform(n, *self.cfg.velocity), self.next_speed)
        direction = torch.stack([angle.cos(), angle.sin()], -1)
        kick = torch.where(due, speed, 0.0).unsqueeze(-1) * direction
        physics.qvel[:, :2] += kick.to(physics.qvel.dtype)  # the free joint's world-frame linear velocity
        yaw = yaw_of(robot.base_quat)
        pushed = {
            "next_speed": math.nan, "next_angle": math.nan, "direction": direction, "origin": robot.base_pos[:, :2],
            "com_origin": robot.com_pos[:, :2], "origin_height": robot.base_pos[:, 2], "ref_yaw": yaw,
            "ref_offset": 0.0, "ref_vel": rotate(commands[:, :2], yaw), "max_deviation": 0.0,
            "max_com_deviation": 0.0, "window": self.window_steps,
            "countdown": self._interval(n),
        }
        for name, value in pushed.items():
            current = getattr(self, name)
            mask = due.view(-1, *([1] * (current.dim() - 1)))
            current.copy_(torch.where(mask, value, current))  # a Python number stays on the host side

    def advance_reference(self, commands: torch.Tensor) -> None:
        """Move the reference by one policy step of the commanded twist [N, (forward, sideways, yaw rate)], along
        the arc it takes a body (envs/g1/commanded_path.py)."""
        v, turn = commands[:, :2], commands[:, 2] * self.dt
        if not self.cfg.reference_turns:
            turn = torch.zeros_like(turn)
        step = arc_step(v, turn, self.dt)
        self.ref_offset = self.ref_offset + rotate(step, self.ref_yaw)
        self.ref_yaw = self.ref_yaw + turn
        self.ref_vel = rotate(v, self.ref_yaw)

    def deviation(self, robot: RobotState) -> torch.Tensor:
        """[N, 2] base position minus the reference."""
        return robot.base_pos[:, :2] - (self.origin + self.ref_offset)

    def timing(self) -> torch.Tensor:
        """[N, 2] the window's share still to come, and the time to the next push as a share of the longest
        interval, both in [0, 1]."""
        next_push = self.countdown.float() * self.dt / max(self.cfg.interval_s[1], self.dt)
        return torch.stack([self.window.float() / max(1, self.window_steps), next_push.clamp(0.0, 1.0)], dim=-1)

    def height_change(self, robot: RobotState) -> torch.Tensor:
        """[N] base height minus its height at the push, m (a fall: about -0.5)."""
        return robot.base_pos[:, 2] - self.origin_height

    def com_deviation(self, robot: RobotState) -> torch.Tensor:
        """[N, 2] whole-body COM minus its reference."""
        return robot.com_pos[:, :2] - (self.com_origin + self.ref_offset)

    def relative_velocity_along_push(self, robot: RobotState) -> torch.Tensor:
        """[N] |(v_base - v_ref) . d|: motion along the push relative to the reference's velocity now, m/s."""
        return ((robot.base_lin_vel_w[:, :2] - self.ref_vel) * self.direction).sum(-1).abs()

    def track(self, robot: RobotState, commands: torch.Tensor) -> None:
        """After the physics step: advance the reference by the step's command and keep the largest deviations
        inside the window."""
        self.advance_reference(commands)
        inside = self.active
        self.max_deviation = torch.where(
            inside, torch.maximum(self.max_deviation, self.deviation(robot).norm(dim=-1)), self.max_deviation)
        self.max_com_deviation = torch.where(
            inside, torch.maximum(self.max_com_deviation, self.com_deviation(robot).norm(dim=-1)),
            self.max_com_deviation)

    def closing(self) -> torch.Tensor:
        """[N] bool: windows that end with this step."""
        return self.window == 1

    def advance_window(self) -> None:
        self.window = (self.window - 1).clamp(min=0)

