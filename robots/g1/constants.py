"""Unitree G1 (29-DoF, rev 1.0) constants: joint sets, motors, PD gains, default pose.

Provenance:
- Motor classes per joint, effort limits and reflected rotor inertia (armature) follow the values published with
  mjlab's and HybridRobotics' whole_body_tracking G1 configs (Unitree motor specs: 5020, 7520-14, 7520-22, 4010;
  the ankle and waist roll/pitch joints are driven by two 5020 motors through a linkage: twice the armature,
  50 Nm).
- Gains from mjlab's armature rule: a 10 Hz natural frequency and damping ratio 2 per joint,
  kp = I w^2, kd = 2 zeta I w. Chosen because it scales each joint's stiffness with the inertia its motor reflects,
  rather than hand-tuned numbers that assume one simulator's joint model.
- Default standing pose: knees slightly bent, as mjlab's G1 "knees bent" keyframe (pelvis at 0.76 m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

LEG_JOINTS = [
    f"{side}_{name}_joint"
    for side in ("left", "right")
    for name in ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch", "ankle_roll")
]
ARM_JOINTS_WALK = [
    f"{side}_{name}_joint" for side in ("left", "right") for name in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow")
]
ARM_JOINTS_RECOVERY = [
    f"{side}_{name}_joint"
    for side in ("left", "right")
    for name in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_roll")
]
WALK_JOINTS = LEG_JOINTS + ARM_JOINTS_WALK  # 20
FALL_RECOVERY_JOINTS = LEG_JOINTS + ["waist_yaw_joint"] + ARM_JOINTS_RECOVERY  # 23
WAIST_JOINTS = ["waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint"]
WRIST_JOINTS = [f"{side}_wrist_{axis}_joint" for side in ("left", "right") for axis in ("roll", "pitch", "yaw")]
WALK_HELD_JOINTS = WAIST_JOINTS + WRIST_JOINTS  # 9: with WALK_JOINTS, all 29
FALL_RECOVERY_HELD_JOINTS = [j for j in WAIST_JOINTS + WRIST_JOINTS if j not in FALL_RECOVERY_JOINTS]  # 6


@dataclass(frozen=True)
class Motor:
    armature: float  # kg m^2, reflected rotor inertia
    effort_limit: float  # Nm


MOTOR_5020 = Motor(0.003609725, 25.0)
MOTOR_7520_14 = Motor(0.010177520, 88.0)
MOTOR_7520_22 = Motor(0.025101925, 139.0)
MOTOR_4010 = Motor(0.00425, 5.0)
MOTOR_DOUBLE_5020 = Motor(2 * MOTOR_5020.armature, 50.0)  # ankle, waist roll/pitch: two 5020 through a linkage

NATURAL_FREQUENCY = 10.0 * 2.0 * math.pi  # rad/s
DAMPING_RATIO = 2.0


def joint_motor(joint: str) -> Motor:
    """The motor driving a G1 joint."""
    if any(k in joint for k in ("hip_pitch", "hip_yaw", "waist_yaw")):
        return MOTOR_7520_14
    if any(k in joint for k in ("hip_roll", "knee")):
        return MOTOR_7520_22
    if any(k in joint for k in ("ankle", "waist_roll", "waist_pitch")):
        return MOTOR_DOUBLE_5020
    if any(k in joint for k in ("wrist_pitch", "wrist_yaw")):
        return MOTOR_4010
    if any(k in joint for k in ("shoulder", "elbow", "wrist_roll")):
        return MOTOR_5020
    raise ValueError(f"Unknown G1 joint '{joint}'.")


def joint_gains(joint: str) -> tuple[float, float]:
    """(kp, kd) from the armature rule."""
    armature = joint_motor(joint).armature
    return armature * NATURAL_FREQUENCY**2, 2.0 * DAMPING_RATIO * armature * NATURAL_FREQUENCY


def holding_gains(joint: str) -> tuple[float, float]:
    """(kp, kd) that hold a joint a policy does not drive at the default pose: on the robot (pchc-deploy) and, with
    ``G1EnvConfig.held_joints``, in training. A walker trained with its waist welded fell over or drifted when the
    waist was held as softly as the armature rule's gains (kp 40 let it drift 0.3 m in 10 s against 2.8 m with a
    stiff waist, in pchc-deploy's simulator), so these are the stiffer holding gains of unitree_rl_gym's G1 deploy
    config: waist 300 / 3, wrists 20 / 1; the rest keep the armature rule."""
    if joint.startswith("waist"):
        return 300.0, 3.0
    if "wrist" in joint:
        return 20.0, 1.0
    return joint_gains(joint)


STANDING_HEIGHT = 0.76
DEFAULT_POSE = {
    "left_hip_pitch_joint": -0.312,
    "right_hip_pitch_joint": -0.312,
    "left_knee_joint": 0.669,
    "right_knee_joint": 0.669,
    "left_ankle_pitch_joint": -0.363,
    "right_ankle_pitch_joint": -0.363,
    "left_shoulder_pitch_joint": 0.2,
    "right_shoulder_pitch_joint": 0.2,
    "left_shoulder_roll_joint": 0.2,
    "right_shoulder_roll_joint": -0.2,
    "left_elbow_joint": 0.6,
    "right_elbow_joint": 0.6,
}
"""Joint angles (rad) of the standing pose; joints not listed are 0."""

FOOT_SITES = ("left_foot", "right_foot")
FOOT_BODIES = ("left_ankle_roll_link", "right_ankle_roll_link")
BASE_BODY = "pelvis"
IMU_SITE = "imu_in_pelvis"
