"""Pushes: horizontal velocity kicks on the pelvis or forces on a body, and what the paper measures after each.

A force push (``PushConfig.force``) acts on one body (torso, pelvis, a limb) over tenths of a second, as a hand or a
door pushes a robot: it turns the robot as it moves it. Its window, direction and reference start at its onset, as a
kick's do.

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
from pchc_rsl.envs.g1.draws import uniform
from pchc_rsl.envs.g1.robot_state import RobotState, yaw_of


def check_push_config(cfg: PushConfig, body_names: list[str]) -> None:
    """ValueError naming the setting when a push config cannot work on a robot with these bodies."""
    force = cfg.force
    for name, (low, high) in (("velocity", cfg.velocity), ("force.magnitude", force.magnitude),
                              ("force.duration_s", force.duration_s)):
        if not 0 <= low <= high:
            raise ValueError(f"env.push.{name} {(low, high)} must be a range 0 <= low <= high.")
    if not -1 <= force.vertical[0] <= force.vertical[1] <= 1:
        raise ValueError(f"env.push.force.vertical {tuple(force.vertical)} must be a range within [-1, 1] (a share "
                         "of the magnitude).")
    if cfg.velocity_share < 0 or force.share < 0 or cfg.velocity_share + force.share <= 0:
        raise ValueError(f"env.push.velocity_share {cfg.velocity_share} and env.push.force.share {force.share} must "
                         "be >= 0 with a positive sum.")
    if force.share > 0:
        unknown = [b for b in force.bodies if b not in body_names]
        if unknown:
            raise ValueError(f"env.push.force.bodies names {unknown}, which the G1 model lacks; bodies: "
                             f"{', '.join(body_names)}.")
        if not force.bodies or any(w < 0 for w in force.bodies.values()) or sum(force.bodies.values()) <= 0:
            raise ValueError(f"env.push.force.bodies {force.bodies} needs weights >= 0 with a positive sum.")


class Pushes:
    """N envs' pushes: when each comes, what it is (a kick or a force, drawn by the config's shares), and the window,
    reference and deviations after it."""

    def __init__(self, cfg: PushConfig, num_envs: int, dt: float, generator: torch.Generator,
                 body_ids: dict[str, int] | None = None, robot_mass: float = 1.0) -> None:
        """``body_ids``: body name -> MuJoCo body id, for force pushes; ``robot_mass`` (kg): the whole robot's, to
        express a force push's impulse as the velocity it gives the robot (``size``)."""
        self.cfg, self.dt, self.generator, self.robot_mass = cfg, dt, generator, robot_mass
        n, self.device = num_envs, generator.device
        self.forces_on = cfg.enabled and cfg.force.share > 0
        """Whether pushes can be forces (a setting, so no step waits on the device to find out)."""
        names = list(cfg.force.bodies)
        self.force_body_ids = torch.tensor([(body_ids or {})[b] for b in names] if self.forces_on else [0],
                                           dtype=torch.long, device=self.device)
        self.force_body_weights = torch.tensor([cfg.force.bodies[b] for b in names] if self.forces_on else [1.0],
                                               device=self.device)
        self.force = torch.zeros(n, 3, device=self.device)
        """[N, 3] the force of each env's push now, N, world frame (0 without one)."""
        self.force_body = torch.zeros(n, dtype=torch.long, device=self.device)
        """[N] the MuJoCo body id it acts on."""
        self.force_left_s = torch.zeros(n, device=self.device)
        """[N] how long it still acts, s."""
        self.countdown = torch.zeros(n, dtype=torch.long, device=self.device)
        """Policy steps until the next push."""
        self.window = torch.zeros(n, dtype=torch.long, device=self.device)
        """Policy steps left in the after-disturb window."""
        self.direction = torch.zeros(n, 2, device=self.device)
        self.size = torch.zeros(n, device=self.device)
        """[N] the last push's size as the horizontal velocity it gives the whole robot, m/s: a kick's speed, a force's
        horizontal part x its duration / the robot's mass."""
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
        self.next_force = torch.full((n,), math.nan, device=self.device)
        self.next_duration = torch.full((n,), math.nan, device=self.device)
        self.next_body = torch.full((n,), -1, dtype=torch.long, device=self.device)
        """A requested force push's magnitude (N), duration (s) and body id; NaN or -1: no force requested."""

    def request(self, env_id: int, speed: float | None = None, angle: float | None = None,
                force: float | None = None, duration_s: float = 0.08, body_id: int | None = None) -> None:
        """Push env ``env_id`` at its next counting step (the viewers' push button), at this speed and angle
        instead of drawn ones where given; with ``force`` (N), a force of that magnitude for ``duration_s`` on body
        ``body_id`` instead of a kick."""
        self.countdown[env_id] = 1
        self.next_speed[env_id] = math.nan if speed is None else speed
        self.next_angle[env_id] = math.nan if angle is None else angle
        self.next_force[env_id] = math.nan if force is None else force
        self.next_duration[env_id] = duration_s
        self.next_body[env_id] = -1 if force is None else int(body_id)

    def _uniform(self, n: int, low: float, high: float) -> torch.Tensor:
        return uniform(self.generator, n, low, high)

    def _interval(self, n: int) -> torch.Tensor:
        return (self._uniform(n, *self.cfg.interval_s) / self.dt).long().clamp(min=1)

    def reset(self, env_ids: torch.Tensor) -> None:
        self.countdown[env_ids] = self._interval(len(env_ids))
        self.window[env_ids] = 0
        self.max_deviation[env_ids] = 0.0
        self.max_com_deviation[env_ids] = 0.0
        self.force_left_s[env_ids] = 0.0

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
        kicked, size = due, speed
        if physics.body_forces is not None:  # physics that takes body forces (every G1 env's)
            forced, force_size = self._start_forces(due, direction)
            kicked, size = due & ~forced, torch.where(forced, force_size, speed)
        kick = torch.where(kicked, speed, 0.0).unsqueeze(-1) * direction
        physics.qvel[:, :2] += kick.to(physics.qvel.dtype)  # the free joint's world-frame linear velocity
        yaw = yaw_of(robot.base_quat)
        pushed = {
            "next_speed": math.nan, "next_angle": math.nan, "direction": direction, "size": size,
            "origin": robot.base_pos[:, :2], "com_origin": robot.com_pos[:, :2], "origin_height": robot.base_pos[:, 2],
            "ref_yaw": yaw, "ref_offset": 0.0, "ref_vel": rotate(commands[:, :2], yaw), "max_deviation": 0.0,
            "max_com_deviation": 0.0, "window": self.window_steps,
            "countdown": self._interval(n), "next_force": math.nan, "next_body": -1,
        }
        for name, value in pushed.items():
            current = getattr(self, name)
            mask = due.view(-1, *([1] * (current.dim() - 1)))
            current.copy_(torch.where(mask, value, current))  # a Python number stays on the host side

    def _start_forces(self, due: torch.Tensor, direction: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Where ``due``, start force pushes: drawn by their share (from the config) or requested (a requested kick
        stays a kick); returns [N] bool, which of the due pushes are forces, and [N] their size (m/s, see ``size``).
        ``direction`` [N, 2]: the horizontal direction of each push."""
        n, force_cfg = len(due), self.cfg.force
        requested = self.next_body >= 0
        kick_requested = ~self.next_speed.isnan()
        if self.forces_on:
            total = self.cfg.velocity_share + force_cfg.share
            drawn = torch.rand(n, generator=self.generator, device=self.device) < force_cfg.share / total
            pick = torch.multinomial(self.force_body_weights, n, replacement=True, generator=self.generator)
            body = torch.where(requested, self.next_body, self.force_body_ids[pick])
            magnitude = torch.where(requested, self.next_force, self._uniform(n, *force_cfg.magnitude))
            duration = torch.where(requested, self.next_duration, self._uniform(n, *force_cfg.duration_s))
            vertical = torch.where(requested, 0.0, self._uniform(n, *force_cfg.vertical))
            forced = (drawn & ~kick_requested) | requested
        else:
            body, magnitude, duration = self.next_body, self.next_force, self.next_duration
            vertical = torch.zeros(n, device=self.device)
            forced = requested
        horizontal = (1 - vertical**2).clamp(min=0.0).sqrt()
        force = magnitude.unsqueeze(-1) * torch.cat([horizontal.unsqueeze(-1) * direction, vertical.unsqueeze(-1)], -1)
        starts = due & forced
        self.force = torch.where(starts.unsqueeze(-1), force, self.force)
        self.force_body = torch.where(starts, body, self.force_body)
        self.force_left_s = torch.where(starts, duration, self.force_left_s)
        return forced, (magnitude * horizontal * duration / self.robot_mass).nan_to_num(0.0)

    def add_forces(self, physics) -> None:
        """Add each env's ongoing force push to the physics' body forces for this step (after the task set its own):
        the whole force while it lasts the step, its share in the step where it ends (impulse = force x duration)."""
        if physics.body_forces is None:
            return
        share = (self.force_left_s / self.dt).clamp(0.0, 1.0)  # [N]
        on_body = torch.nn.functional.one_hot(self.force_body, physics.body_forces.shape[1])  # [N, nbody]
        applied = (share.unsqueeze(-1) * self.force).unsqueeze(1) * on_body.unsqueeze(-1)  # [N, nbody, 3]
        physics.body_forces[:, :, :3] += applied.to(physics.body_forces.dtype)
        self.force_left_s = (self.force_left_s - self.dt).clamp(min=0.0)

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

