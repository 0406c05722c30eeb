"""The policy as it runs on the robot: observation frames built from the robot's state exactly as training built
them (the layout comes from the ONNX file's metadata, not from a training config), the same history, one action.
"""

from __future__ import annotations

import numpy as np

from pchc_rsl.deploy.g1_motors import JointMap
from pchc_rsl.deploy.live_controls import command_ranges_of
from pchc_rsl.deploy.robot_io import RobotState
from pchc_rsl.export.onnx_policy import OnnxPolicy

FRAME_QUANTITIES = {"base_ang_vel", "projected_gravity", "joint_pos_minus_default", "joint_vel", "last_action",
                    "action_scale_eta", "velocity_command"}
"""The quantities a format-1 frame may hold; anything else is a file this deploy does not understand."""


class PolicyStep:
    """``q_target = step(state, preference, command)``: one control period of the policy, in the policy's joint
    order. ``reset(state)`` fills the history with the current frame, as training does at a reset."""

    def __init__(self, path: str) -> None:
        self.policy = OnnxPolicy(path, num_threads=1)
        meta = self.policy.metadata
        if "action_scale_eta" not in meta or "joint_range" not in meta:
            raise ValueError(f"{path} lacks the action scale and joint ranges a deploy needs; re-export it: "
                             f"pchc-export-onnx CHECKPOINT.pt -o {path} --force")
        self.meta = meta
        self.task = meta.get("task", "?")
        self.joints = JointMap(meta["joint_names"])
        self.default_pos = np.array(meta["default_joint_pos"])
        self.action_scale = np.array(meta["action_scale"])
        self.action_clip = float(meta["action_clip"])
        self.kp, self.kd = np.array(meta["kp"]), np.array(meta["kd"])
        self.effort_limit = np.array(meta["effort_limit"])
        self.joint_range = np.array(meta["joint_range"])
        self.control_period = float(meta["control_period_s"])
        self.objective_names = list(meta["objective_names"])
        layout = meta["observation"]
        unknown = [name for name, _ in layout["frame"] if name not in FRAME_QUANTITIES]
        if unknown:
            raise ValueError(f"{path}: observation quantities {unknown} are unknown to this pchc-deploy; update "
                             "pchc-rsl or re-export the policy with this version.")
        self.frame_layout = [(name, int(size)) for name, size in layout["frame"]]
        self.command_ranges, self.command_note = command_ranges_of(meta)
        self.uses_command = self.command_ranges is not None
        self.history = np.zeros((int(layout["frames"]), int(layout["frame_dim"])), np.float32)
        if self.history.size != self.policy.obs_dim:
            raise ValueError(f"{path}: the metadata's observation ({self.history.shape}) does not match the "
                             f"network's input ({self.policy.obs_dim}).")
        self.last_action = np.zeros(len(self.default_pos))

    def frame(self, state: RobotState, command: np.ndarray) -> np.ndarray:
        parts = {
            "base_ang_vel": state.gyro,
            "projected_gravity": state.projected_gravity(),
            "joint_pos_minus_default": self.joints.to_policy(state.q) - self.default_pos,
            "joint_vel": self.joints.to_policy(state.dq),
            "last_action": self.last_action,
            "action_scale_eta": [self.meta["action_scale_eta"]],
            "velocity_command": command,
        }
        frame = np.concatenate([np.asarray(parts[name], np.float64).reshape(-1) for name, _ in self.frame_layout])
        return frame.astype(np.float32)

    def reset(self, state: RobotState, command: np.ndarray | None = None) -> None:
        self.last_action[:] = 0.0
        self.history[:] = self.frame(state, self._command(command))

    def __call__(self, state: RobotState, preference: np.ndarray, command: np.ndarray | None = None) -> np.ndarray:
        """Push the newest frame, run the network, return the joint targets [J] (policy order)."""
        self.history[1:] = self.history[:-1]
        self.history[0] = self.frame(state, self._command(command))
        preference = np.asarray(preference, np.float32).reshape(1, -1)  # OnnxPolicy checks it is on the simplex
        action = self.policy(self.history.reshape(1, -1), preference)[0]
        self.last_action = np.clip(action, -self.action_clip, self.action_clip).astype(np.float64)
        return self.default_pos + self.action_scale * self.last_action

    def _command(self, command: np.ndarray | None) -> np.ndarray:
        return np.zeros(3) if command is None else np.asarray(command, np.float64)
