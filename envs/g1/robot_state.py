"""The robot's state as torch tensors, read from the batched physics after every step or reset."""

from __future__ import annotations

import mujoco
import torch


def quat_rotate_inverse(q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Rotate world vectors v [N, 3] into the frame of unit quaternions q [N, 4] (w, x, y, z)."""
    w, xyz = q[:, :1], q[:, 1:]
    t = 2.0 * torch.cross(xyz, v, dim=-1)
    return v - w * t + torch.cross(xyz, t, dim=-1)


def yaw_of(q: torch.Tensor) -> torch.Tensor:
    w, x, y, z = q.unbind(-1)
    return torch.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


class RobotState:
    """Base pose and velocities, joints, feet, torques and whole-body COM of all envs (float32, on the physics'
    device).

    Sensor columns are looked up by name once; ``read`` is on the hot path and only slices.
    """

    def __init__(self, physics, model: mujoco.MjModel, joints: list[str]) -> None:
        self.physics = physics
        self.num_envs = physics.num_envs
        dev = physics.device
        self.gravity = torch.tensor([0.0, 0.0, -1.0], device=dev).expand(self.num_envs, 3)
        self.joint_qpos_idx = torch.tensor([model.jnt_qposadr[model.joint(j).id] for j in joints], device=dev)
        self.joint_dof_idx = torch.tensor([model.jnt_dofadr[model.joint(j).id] for j in joints], device=dev)
        feet = ("left_foot", "right_foot")

        def columns(name: str) -> list[int]:
            sensor = model.sensor(name)
            return list(range(int(sensor.adr[0]), int(sensor.adr[0] + sensor.dim[0])))

        index = {
            "foot_pos": [columns(f"{s}_pos") for s in feet],  # [2, 3]
            "foot_vel": [columns(f"{s}_linvel") for s in feet],  # [2, 3]
            "foot_touch": [columns(f"{s}_touch")[0] for s in feet],  # [2]
            "com_pos": columns("com_pos"),  # [3]
            "com_vel": columns("com_vel"),  # [3]
            "torque": [columns(f"{j}_torque")[0] for j in joints],  # [J]
        }
        self.sensor_index = {key: torch.tensor(value, device=dev) for key, value in index.items()}
        self.read()

    def read(self) -> None:
        """Pull the latest physics state and the substep sensors into torch tensors."""
        p = self.physics
        qpos, qvel = p.qpos.float(), p.qvel.float()
        self.base_pos = qpos[:, :3]
        self.base_quat = qpos[:, 3:7]
        self.base_lin_vel_w = qvel[:, :3]
        self.base_ang_vel = qvel[:, 3:6]  # free joint: angular velocity in the body frame
        self.base_lin_vel = quat_rotate_inverse(self.base_quat, self.base_lin_vel_w)
        yaw = self.yaw = yaw_of(self.base_quat)
        self.heading = torch.stack([yaw.cos(), yaw.sin()], dim=-1)
        """[N, 2] the base's forward direction in the horizontal plane (world frame)."""
        self.projected_gravity = quat_rotate_inverse(self.base_quat, self.gravity)
        self.joint_pos = qpos[:, self.joint_qpos_idx]
        self.joint_vel = qvel[:, self.joint_dof_idx]
        sensors = p.substep_sensors.float()  # [N, K, S]
        index = self.sensor_index
        self.foot_pos = sensors[:, -1, index["foot_pos"]]  # [N, 2, 3]
        self.foot_vel = sensors[:, -1, index["foot_vel"]]
        self.foot_touch_substeps = sensors[:, :, index["foot_touch"]]  # [N, K, 2]
        self.com_pos = sensors[:, -1, index["com_pos"]]  # [N, 3]
        self.com_vel = sensors[:, -1, index["com_vel"]]  # [N, 3], world frame
        self.torques_substeps = sensors[:, :, index["torque"]]  # [N, K, J]
        self.joint_vel_substeps = p.substep_qvel[:, :, self.joint_dof_idx].float()  # [N, K, J]
        self.torques = self.torques_substeps[:, -1]
