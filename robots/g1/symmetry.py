"""The G1's left-right mirror: the reflection y -> -y of the world through the robot's sagittal (x-z) plane.

Under it the left and right joints swap, and a joint whose axis lies in the sagittal plane's normal direction keeps
its sign (pitch: axis y) while roll (axis x) and yaw (axis z) joints change sign: the menagerie G1 gives both sides'
roll and yaw joints the same axis and mirrored ranges (left hip roll -0.52..2.97 rad, right -2.97..0.52), so the
mirror of the left angle q is the right angle -q. Vectors: a polar vector (velocity, gravity, position) negates its
y component; an axial vector (angular velocity) keeps its y component and negates x and z.
"""

from __future__ import annotations

import mujoco
import numpy as np


def mirror_joint_name(joint: str) -> str:
    """left_* <-> right_*; a joint on the sagittal plane (waist) is its own mirror."""
    if joint.startswith("left_"):
        return "right_" + joint[len("left_"):]
    if joint.startswith("right_"):
        return "left_" + joint[len("right_"):]
    return joint


def mirror_joint_sign(joint: str) -> float:
    """-1 for roll and yaw joints (axis x or z), +1 for pitch joints and the knee and elbow (axis y)."""
    return -1.0 if ("_roll" in joint or "_yaw" in joint) else 1.0


def joint_mirror(joints: list[str]) -> tuple[list[int], list[float]]:
    """(index, sign) such that mirrored[:, i] = sign[i] * values[:, index[i]] for values ordered as ``joints``."""
    position = {name: i for i, name in enumerate(joints)}
    index, sign = [], []
    for joint in joints:
        partner = mirror_joint_name(joint)
        if partner not in position:
            raise ValueError(f"'{joint}' has no mirror partner '{partner}' among the joints {joints}.")
        index.append(position[partner])
        sign.append(mirror_joint_sign(joint))
    return index, sign


def mirror_polar(v: np.ndarray) -> np.ndarray:
    """[..., 3] polar vectors (positions, velocities, gravity): (x, y, z) -> (x, -y, z)."""
    return v * np.array([1.0, -1.0, 1.0])


def mirror_axial(w: np.ndarray) -> np.ndarray:
    """[..., 3] axial vectors (angular velocities): (x, y, z) -> (-x, y, -z)."""
    return w * np.array([-1.0, 1.0, -1.0])


def mirror_quaternion(q: np.ndarray) -> np.ndarray:
    """[..., 4] orientation (w, x, y, z) -> its mirror: the rotation R' = M R M with M = diag(1, -1, 1), which is
    (w, -x, y, -z)."""
    return q * np.array([1.0, -1.0, 1.0, -1.0])


def mirror_free_state(model, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mirror a MuJoCo state of the G1 with a free base joint: base position and orientation, base linear (world)
    and angular (body frame) velocity, and every hinge joint swapped with its partner and signed."""
    qpos, qvel = np.array(qpos, dtype=float), np.array(qvel, dtype=float)
    out_pos, out_vel = qpos.copy(), qvel.copy()
    out_pos[..., 0:3] = mirror_polar(qpos[..., 0:3])
    out_pos[..., 3:7] = mirror_quaternion(qpos[..., 3:7])
    out_vel[..., 0:3] = mirror_polar(qvel[..., 0:3])
    out_vel[..., 3:6] = mirror_axial(qvel[..., 3:6])
    for j in range(model.njnt):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            continue
        name = model.joint(j).name
        partner = model.joint(mirror_joint_name(name))
        sign = mirror_joint_sign(name)
        out_pos[..., model.jnt_qposadr[j]] = sign * qpos[..., model.jnt_qposadr[partner.id]]
        out_vel[..., model.jnt_dofadr[j]] = sign * qvel[..., model.jnt_dofadr[partner.id]]
    return out_pos, out_vel
