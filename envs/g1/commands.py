"""The walker's velocity command and what follows it: drawn at a reset and whenever its countdown runs out, held in
between; the heading and path it integrates to (the heading and position holds' references) and the base's
averaged velocity that the average-tracking terms compare with it."""

from __future__ import annotations

import math

import torch

from pchc_rsl.envs.g1.commanded_path import CommandedPath
from pchc_rsl.envs.g1.config import G1EnvConfig
from pchc_rsl.envs.g1.draws import chance, uniform
from pchc_rsl.envs.g1.robot_state import RobotState


def wrap_angle(angle: torch.Tensor) -> torch.Tensor:
    """Into [-pi, pi)."""
    return torch.remainder(angle + math.pi, 2 * math.pi) - math.pi


class VelocityCommands:
    """N commands (v_x, v_y, w_z) in the base frame; see G1EnvConfig's command settings."""

    def __init__(self, cfg: G1EnvConfig, num_envs: int, dt: float, max_episode_length: int,
                 generator: torch.Generator) -> None:
        self.cfg, self.dt, self.max_episode_length, self.generator = cfg, dt, max_episode_length, generator
        n, dev = num_envs, generator.device
        self.values = torch.zeros(n, 3, device=dev)
        """[N, (v_x, v_y, w_z)] what each robot is told now (m/s, m/s, rad/s)."""
        self.countdown = torch.zeros(n, dtype=torch.long, device=dev)
        """[N] policy steps until each env's next command."""
        self.heading_error = torch.zeros(n, device=dev)
        """[N] the base's yaw minus the yaw its commands integrate to since the command was set (rad, wrapped)."""
        self.path = CommandedPath(n, dt, dev)
        """Where each env's commands take it since the command was set or a push's window closed (the position
        hold's reference; during a window the disturbance objective measures the drift instead)."""
        self.velocity_average = torch.zeros(n, 3, device=dev)
        """[N, (v_x, v_y, w_z)] the base's forward and sideways speed (base frame) and yaw rate, averaged over about
        ``velocity_average_s`` (an exponential average): a walker's velocity sways with every step, and a kernel on
        the instantaneous value pays a walker that is right on average little more than one that is off."""
        self.previous_yaw = torch.zeros(n, device=dev)
        """[N] the base's yaw at the last step (rad): its per-step change, summed, is the turn unwrapped."""
        self.turn = torch.zeros(n, device=dev)
        """[N] the base's turn over the last step (rad)."""

    def draw(self, n: int) -> torch.Tensor:
        """[n, 3] (v_x, v_y, w_z) uniform in the command ranges, zero (stand) with ``zero_command_probability``, one
        axis alone with ``single_axis_probability``."""
        r, g = self.cfg.command_ranges, self.generator
        drawn = torch.stack([uniform(g, n, *r["lin_vel_x"]), uniform(g, n, *r["lin_vel_y"]),
                             uniform(g, n, *r["ang_vel_z"])], 1)
        commands = drawn.clone()
        if self.cfg.zero_yaw_rate_probability > 0:
            straight = chance(g, n, self.cfg.zero_yaw_rate_probability)
            commands[:, 2] = torch.where(straight, 0.0, commands[:, 2])
        if self.cfg.single_axis_probability > 0:
            single = chance(g, n, self.cfg.single_axis_probability)
            axis = torch.randint(0, 3, (n,), generator=g, device=g.device)
            alone = torch.nn.functional.one_hot(axis, 3).bool()
            commands = torch.where(single.unsqueeze(-1), torch.where(alone, drawn, 0.0), commands)
        if self.cfg.zero_command_probability > 0:
            standing = chance(g, n, self.cfg.zero_command_probability)
            commands = torch.where(standing.unsqueeze(-1), 0.0, commands)
        return commands

    def _interval(self, n: int) -> torch.Tensor:
        """[n] policy steps until the next command (a step count past the episode's end without resampling)."""
        if self.cfg.command_resample_s is None:
            return torch.full((n,), self.max_episode_length + 1, dtype=torch.long, device=self.generator.device)
        seconds = uniform(self.generator, n, *self.cfg.command_resample_s)
        return (seconds / self.dt).round().long().clamp(min=1)

    def reset(self, env_ids: torch.Tensor) -> None:
        """Draw these envs' new commands and their countdowns."""
        n = len(env_ids)
        self.values[env_ids] = self.draw(n)
        self.countdown[env_ids] = self._interval(n)

    def restart_tracking(self, env_ids: torch.Tensor, restarted: torch.Tensor, robot: RobotState) -> None:
        """A new episode in these envs (``restarted``: the same as a mask): path, heading and averages start over
        at the robot's pose."""
        self.previous_yaw[env_ids] = robot.yaw[env_ids]
        self.velocity_average[env_ids] = 0.0
        self.heading_error[env_ids] = 0.0
        self.path.restart(restarted, robot.base_pos[:, :2], robot.yaw)

    def track(self, robot: RobotState, pushed: torch.Tensor) -> None:
        """After the physics step: the path moves on (and starts again where a push's window is open), the turn,
        heading error and averaged velocity take in the new state."""
        self.path.advance(self.values)
        self.path.restart(pushed, robot.base_pos[:, :2], robot.yaw)
        self.turn = wrap_angle(robot.yaw - self.previous_yaw)
        self.previous_yaw = robot.yaw.clone()
        self.heading_error = wrap_angle(self.heading_error + self.turn - self.values[:, 2] * self.dt)
        velocity = torch.cat([robot.base_lin_vel[:, :2], (self.turn / self.dt).unsqueeze(-1)], dim=-1)
        self.velocity_average += min(1.0, self.dt / self.cfg.velocity_average_s) * (velocity - self.velocity_average)

    def resample_due(self, robot: RobotState) -> None:
        """Count down each env's command; where it ran out draw a new one (batched: no host sync)."""
        if self.cfg.command_resample_s is None:
            return
        self.countdown -= 1
        due = self.countdown <= 0
        self.values = torch.where(due.unsqueeze(-1), self.draw(len(due)), self.values)
        self.heading_error = torch.where(due, 0.0, self.heading_error)
        self.path.restart(due, robot.base_pos[:, :2], robot.yaw)
        self.countdown = torch.where(due, self._interval(len(due)), self.countdown)
