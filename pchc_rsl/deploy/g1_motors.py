"""The G1's 29 motors in the order of unitree_sdk2's hg LowCmd/LowState, and the map from a policy's joints to them.

A policy drives a subset of the joints (20 for walking, 23 for fall recovery: the rest were welded in training);
on the robot every motor needs a command, so the joints a policy does not drive are held at the default pose by PD
with the gains of the armature rule (robots/g1/constants.py). The most frequent deploy fault in public G1 projects
is a joint-order mismatch, so the map goes by name, never by position.
"""

from __future__ import annotations

import numpy as np

from pchc_rsl.robots.g1.constants import DEFAULT_POSE, holding_gains, joint_gains, joint_motor

MOTOR_JOINTS = [
    *(f"left_{n}_joint" for n in ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch", "ankle_roll")),
    *(f"right_{n}_joint" for n in ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch", "ankle_roll")),
    "waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint",
    *(f"left_{n}_joint" for n in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_roll",
                                   "wrist_pitch", "wrist_yaw")),
    *(f"right_{n}_joint" for n in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_roll",
                                    "wrist_pitch", "wrist_yaw")),
]
"""Motor i of rt/lowcmd and rt/lowstate (29-DoF G1; slots 29-34 of the 35 are unused)."""

NUM_MOTORS = len(MOTOR_JOINTS)
MOTOR_KP = np.array([joint_gains(j)[0] for j in MOTOR_JOINTS])
MOTOR_KD = np.array([joint_gains(j)[1] for j in MOTOR_JOINTS])
MOTOR_EFFORT_LIMIT = np.array([joint_motor(j).effort_limit for j in MOTOR_JOINTS])
MOTOR_DEFAULT_POS = np.array([DEFAULT_POSE.get(j, 0.0) for j in MOTOR_JOINTS])


MOTOR_HOLD_KP = np.array([holding_gains(j)[0] for j in MOTOR_JOINTS])
MOTOR_HOLD_KD = np.array([holding_gains(j)[1] for j in MOTOR_JOINTS])

_STAND_LEG_KP, _STAND_LEG_KD = [300, 300, 200, 400, 300, 200], [10, 10, 4, 12, 4, 4]
_STAND_ARM_KP, _STAND_ARM_KD = [100, 100, 50, 50, 20, 20, 20], [2, 2, 2, 2, 1, 1, 1]
MOTOR_STAND_KP = np.array(_STAND_LEG_KP * 2 + [300.0] * 3 + _STAND_ARM_KP * 2, dtype=float)
MOTOR_STAND_KD = np.array(_STAND_LEG_KD * 2 + [3.0] * 3 + _STAND_ARM_KD * 2, dtype=float)
"""Gains for the ramp to the default pose and for holding it (HOLD). Waist and arms: unitree_rl_gym's G1 deploy
(deploy/deploy_real/configs/g1.yaml, ``arm_waist_kps``/``arm_waist_kds``), which its deploy_real.py uses for the same
two phases. Legs (hip pitch, roll, yaw, knee, ankle pitch, roll): stiffer than that file's ``kps``/``kds`` (hip 100,
knee 150, ankle 40; kd 2, 4, 2), because a robot held only by PD is an inverted pendulum on its ankles: it stands if
they are stiffer than gravity's tipping stiffness m g h (35 kg x 9.81 x 0.6 m = 206 Nm/rad, about 100 per ankle), and
the hips and knees in series with them must not give way. With unitree_rl_gym's leg gains the G1 tips over within 1.5 s
of the gantry's release. These were chosen in unitree_mujoco's G1 model with its torque semantics (PD computed from
sensor readings one 2 ms physics step old; tools/diagnostics/hold_gains.py): the robot stands, a 25 N push of 0.2 s at
the torso from the front or the back does not tip it, and the free feet do not chatter while it hangs on the gantry (an
ankle pitch kd of 8 makes them chatter there). Less hip and knee damping (kd 6 and 8) tips the robot at 25 N, and in
unitree_mujoco itself once it had drifted forward on the band. In pchc-deploy's simulator these stand at 500 Hz physics
in both PD modes, and with PD at every step down to 250 Hz (at 200 Hz the hip and knee kd tip it). docs/deploy.md has
the figures."""


class JointMap:
    """Index arrays between the policy's joint order and the 29-motor order, built from names."""

    def __init__(self, policy_joints: list[str]) -> None:
        unknown = [j for j in policy_joints if j not in MOTOR_JOINTS]
        if unknown:
            raise ValueError(f"the policy drives joints that a G1 does not have: {unknown}; G1 joints are "
                             f"{MOTOR_JOINTS[0]} ... {MOTOR_JOINTS[-1]} (29, unitree_sdk2's order).")
        if len(set(policy_joints)) != len(policy_joints):
            raise ValueError(f"the policy names a joint twice: {policy_joints}.")
        self.policy_joints = list(policy_joints)
        self.motor_index = np.array([MOTOR_JOINTS.index(j) for j in policy_joints])
        self.held = np.setdiff1d(np.arange(NUM_MOTORS), self.motor_index)

    def to_policy(self, motor_values: np.ndarray) -> np.ndarray:
        """[29] in motor order -> [J] in the policy's order."""
        return np.asarray(motor_values)[self.motor_index]

    def to_motors(self, policy_values: np.ndarray, fill: np.ndarray) -> np.ndarray:
        """[J] in the policy's order -> [29] in motor order, ``fill`` (a [29] array) for the joints not driven."""
        out = np.array(fill, dtype=np.float64, copy=True)
        out[self.motor_index] = policy_values
        return out
