"""The G1's observation groups: noisy history for the actor, noise-free history plus privileged state for the
critic (the paper gives both the same 5 past frames and the current one), and the AMP window."""

from __future__ import annotations

import torch
from tensordict import TensorDict

from pchc_rsl.amp.motion import ROOT_VELOCITY_SIZE
from pchc_rsl.envs.g1.commanded_path import rotate

NOISE_SCALES = {"ang_vel": 0.2, "gravity": 0.05, "joint_pos": 0.01, "joint_vel": 1.5}
"""Half-widths of the uniform observation noise per quantity, multiplied by ``observation_noise``."""


def frame_layout(num_joints: int, use_command: bool) -> list[tuple[str, int]]:
    """The quantities of one frame in order, with their sizes (the deploy metadata and the mirror read it)."""
    layout = [("base_ang_vel", 3), ("projected_gravity", 3), ("joint_pos_minus_default", num_joints),
              ("joint_vel", num_joints), ("last_action", num_joints), ("action_scale_eta", 1)]
    if use_command:
        layout.append(("velocity_command", 3))
    return layout


def amp_frame_layout(num_joints: int, root_velocity: bool) -> list[tuple[str, int]]:
    """The quantities of one AMP frame in order (the mirror reads it): the actuated joint positions, and with
    ``root_velocity`` the base's velocity in its heading frame (pchc_rsl.amp.motion.root_velocity)."""
    return [("joint_pos", num_joints)] + ([("amp_root_velocity", ROOT_VELOCITY_SIZE)] if root_velocity else [])


class ObservationBuffers:
    """Frame histories, newest first: s_t = [angular velocity, gravity in base frame, q - q_default, dq, a_{t-1},
    eta (, command)]; the AMP window holds the actuated joint positions (and the base's velocity), oldest first.
    ``dt``: the control step (s), over which the base's change of position is its velocity in the AMP frame."""

    def __init__(self, num_envs: int, num_joints: int, history_length: int, amp_window: int, use_command: bool,
                 noise: float, generator: torch.Generator, *, dt: float, amp_root_velocity: bool = False) -> None:
        self.use_command, self.noise, self.generator = use_command, noise, generator
        self.frame_layout = frame_layout(num_joints, use_command)
        self.amp_frame_layout = amp_frame_layout(num_joints, amp_root_velocity)
        self.amp_root_velocity, self.dt = amp_root_velocity, dt
        frame_dim = sum(size for _, size in self.frame_layout)
        device = generator.device
        self.policy = torch.zeros(num_envs, history_length + 1, frame_dim, device=device)
        self.critic = torch.zeros(num_envs, history_length + 1, frame_dim, device=device)
        amp_dim = sum(size for _, size in self.amp_frame_layout)
        self.amp = torch.zeros(num_envs, amp_window, amp_dim, device=device)
        self.amp_last_xy = torch.zeros(num_envs, 2, device=device)
        """[N, 2] the base's x, y (world) at the last AMP frame: its velocity is the change over a step, as a clip's
        is over a frame."""

    def frame(self, env, noise: bool = False) -> torch.Tensor:
        """[N, frame_dim] of the current state; with ``noise``, uniform noise on the measured quantities."""
        robot = env.robot
        parts = {
            "ang_vel": robot.base_ang_vel,
            "gravity": robot.projected_gravity,
            "joint_pos": robot.joint_pos - env.default_joint_pos,
            "joint_vel": robot.joint_vel,
        }
        if noise and self.noise > 0:
            parts = {k: v + self.noise * NOISE_SCALES[k] * (2 * self._uniform(v.shape) - 1) for k, v in parts.items()}
        frame = [*parts.values(), env.actions, env.action_scale]
        if self.use_command:
            frame.append(env.commands)
        return torch.cat(frame, dim=-1)

    def _uniform(self, shape: torch.Size) -> torch.Tensor:
        return torch.rand(shape, generator=self.generator, device=self.generator.device)

    def reset(self, env, env_ids: torch.Tensor) -> None:
        """Fill the histories of these envs with their current frame (no noise) and joint positions."""
        frame = self.frame(env)[env_ids].unsqueeze(1)
        self.policy[env_ids] = frame
        self.critic[env_ids] = frame
        self.amp_last_xy[env_ids] = env.robot.base_pos[env_ids, :2]
        frame = env.robot.joint_pos[env_ids]
        if self.amp_root_velocity:
            frame = torch.cat([frame, torch.zeros(len(frame), ROOT_VELOCITY_SIZE, device=frame.device)], dim=-1)
        self.amp[env_ids] = frame.unsqueeze(1)

    def push(self, env, amp: bool = True) -> None:
        """Shift the histories by one step and add the current frame (noisy for the actor); ``amp=False`` when the
        AMP window was already advanced this step."""
        self.policy[:, 1:] = self.policy[:, :-1].clone()
        self.policy[:, 0] = self.frame(env, noise=True)
        self.critic[:, 1:] = self.critic[:, :-1].clone()
        self.critic[:, 0] = self.frame(env)
        if amp:
            self.push_amp(env)

    def push_amp(self, env) -> None:
        self.amp[:, :-1] = self.amp[:, 1:].clone()
        self.amp[:, -1] = self._amp_frame(env)

    def _amp_frame(self, env) -> torch.Tensor:
        """[N, amp frame] the joint positions, with the root velocity the base's change since the last frame in
        its heading now (forward, sideways m/s, yaw rate rad/s: the step's turn, as the commands track it)."""
        if not self.amp_root_velocity:
            return env.robot.joint_pos
        xy = env.robot.base_pos[:, :2]
        moved = rotate(xy - self.amp_last_xy, -env.robot.yaw)
        self.amp_last_xy = xy.clone()
        velocity = torch.cat([moved, env.command.turn.unsqueeze(-1)], dim=-1) / self.dt
        return torch.cat([env.robot.joint_pos, velocity], dim=-1)

    def groups(self, env, privileged: torch.Tensor) -> TensorDict:
        """The observation TensorDict: policy, preference, critic ([history, privileged]) and amp."""
        return TensorDict(
            {
                "policy": self.policy.flatten(1).clone(),
                "preference": env.preference.clone(),
                "critic": torch.cat([self.critic.flatten(1), privileged], dim=-1),
                "amp": self.amp.flatten(1).clone(),
            },
            batch_size=[env.num_envs],
        )
