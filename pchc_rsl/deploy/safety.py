"""The deploy's safety state machine, as G1 owners run a new policy:

wait for state -> zero torque -> ramp to the default pose (2 s) -> hold -> policy -> damping.

No policy command goes out before the ramp has finished. The ramp and the hold use standing gains (unitree's, see
g1_motors.MOTOR_STAND_KP), the policy its own. Damping (kp 0, kd only: the robot sinks slowly instead of collapsing
or kicking) is final, entered on request or by the watchdog: a stale state, a tilt past the limit, a joint outside
its range, or a collapse that does not tilt (a load-bearing joint far from its target for too long: a robot that
sits down keeps its pelvis level).
"""

from __future__ import annotations

import enum

import numpy as np

from pchc_rsl.deploy.g1_motors import (MOTOR_DEFAULT_POS, MOTOR_JOINTS, MOTOR_KD, MOTOR_KP, MOTOR_STAND_KD,
                                       MOTOR_STAND_KP, NUM_MOTORS)
from pchc_rsl.deploy.robot_io import MotorCommand, RobotState

RAMP_S = 2.0
DAMPING_KD = 8.0  # Nm s/rad on every motor (unitree_rl_gym's damping state)
STALE_S = 0.05
"""A state older than this (2.5 control periods) trips the watchdog; the next tick (20 ms) then damps."""
TILT_LIMIT = 0.8
"""Norm of gravity's horizontal part in the pelvis frame (about 53 degrees of tilt)."""
JOINT_MARGIN = 0.1
"""rad past a joint's range before the watchdog trips (encoders read slightly past the soft limits)."""
LOAD_BEARING = np.array([MOTOR_JOINTS.index(f"{side}_{name}_joint") for side in ("left", "right")
                         for name in ("hip_pitch", "knee", "ankle_pitch")])
"""The joints that carry the robot's weight: when they give way it sinks, however level its pelvis."""
COLLAPSE_ERROR = 0.6
"""rad between a load-bearing joint and its target that counts as giving way: a robot sinking to the floor from
the default pose bends its knees by more than 1 rad and stays there."""
COLLAPSE_S = 0.6
"""s a load-bearing joint may stay past COLLAPSE_ERROR before the watchdog damps. A walking gait does this for a
moment: measured in the training env over 10 s at (1, 0) and (0, 1), 16 episodes each, the walkers' longest
stretch past 0.6 rad was 0.14-0.26 s (errors up to 1.75 rad while a leg takes the weight); a collapse stays."""


class Mode(enum.Enum):
    WAIT = "wait for state"
    ZERO_TORQUE = "zero torque"
    RAMP = "ramp to the default pose"
    HOLD = "hold the default pose"
    POLICY = "policy"
    DAMPING = "damping"


class SafetyStateMachine:
    """``command(state, now, policy_targets)`` -> the MotorCommand for this tick; transitions by ``request``."""

    def __init__(self, kp: np.ndarray | None = None, kd: np.ndarray | None = None,
                 default_pos: np.ndarray | None = None, policy_index: np.ndarray | None = None,
                 joint_range: np.ndarray | None = None, stand_kp: np.ndarray | None = None,
                 stand_kd: np.ndarray | None = None) -> None:
        """kp, kd, default_pos: [29] motor arrays (the policy's gains on its joints, holding gains elsewhere);
        policy_index: the motors the policy drives; joint_range: [len(policy_index), 2]; stand_kp, stand_kd: [29]
        gains of the ramp and the hold."""
        self.kp = MOTOR_KP.copy() if kp is None else np.asarray(kp, float)
        self.kd = MOTOR_KD.copy() if kd is None else np.asarray(kd, float)
        self.stand_kp = MOTOR_STAND_KP.copy() if stand_kp is None else np.asarray(stand_kp, float)
        self.stand_kd = MOTOR_STAND_KD.copy() if stand_kd is None else np.asarray(stand_kd, float)
        self.target: np.ndarray | None = None  # the position targets last sent [29]
        self.collapse_error, self.collapse_s = COLLAPSE_ERROR, COLLAPSE_S
        self.giving_way_since: float | None = None
        self.default_pos = MOTOR_DEFAULT_POS.copy() if default_pos is None else np.asarray(default_pos, float)
        self.policy_index = np.arange(NUM_MOTORS) if policy_index is None else np.asarray(policy_index)
        self.joint_range = joint_range
        self.mode = Mode.WAIT
        self.reason = ""
        self.mode_since = 0.0
        self.ramp_from = self.default_pos.copy()

    def request(self, mode: Mode, now: float, state: RobotState | None = None, reason: str = "") -> bool:
        """Ask for a transition; True if taken. Only forward along the sequence, and damping from anywhere."""
        allowed = {Mode.ZERO_TORQUE: {Mode.WAIT}, Mode.RAMP: {Mode.ZERO_TORQUE}, Mode.HOLD: {Mode.RAMP},
                   Mode.POLICY: {Mode.HOLD}, Mode.DAMPING: set(Mode) - {Mode.DAMPING}}
        if self.mode not in allowed[mode]:
            return False
        if mode is Mode.HOLD and now - self.mode_since < RAMP_S:
            return False  # no hold (and so no policy) before the ramp has finished
        if mode is Mode.RAMP:
            if state is None or now - state.received_at > STALE_S:
                return False
            self.ramp_from = state.q.copy()
        self.mode, self.mode_since, self.reason = mode, now, reason
        return True

    def watchdog(self, state: RobotState | None, now: float) -> str:
        """Why the robot must be damped now ('' if it need not). Armed once the motors are driven (from the ramp
        on): in zero torque there is nothing to stop, and the ramp refuses to start from a stale state."""
        if self.mode in (Mode.WAIT, Mode.ZERO_TORQUE, Mode.DAMPING):
            return ""
        if state is None or now - state.received_at > STALE_S:
            age = "none" if state is None else f"{(now - state.received_at) * 1000:.0f} ms old"
            return f"stale LowState ({age})"
        tilt = float(np.linalg.norm(state.projected_gravity()[:2]))
        if self.mode in (Mode.HOLD, Mode.POLICY) and tilt > TILT_LIMIT:
            return f"tilt {np.degrees(np.arcsin(min(tilt, 1.0))):.0f} degrees"
        if self.joint_range is not None and self.mode in (Mode.HOLD, Mode.POLICY):
            q = state.q[self.policy_index]
            out = (q < self.joint_range[:, 0] - JOINT_MARGIN) | (q > self.joint_range[:, 1] + JOINT_MARGIN)
            if out.any():
                joint = MOTOR_JOINTS[int(self.policy_index[np.argmax(out)])]
                return f"{joint} outside its range ({q[np.argmax(out)]:.2f} rad)"
        return self._collapse(state, now)

    def _collapse(self, state: RobotState, now: float) -> str:
        """A load-bearing joint more than COLLAPSE_ERROR from its target for longer than COLLAPSE_S (HOLD, POLICY)."""
        if self.mode not in (Mode.HOLD, Mode.POLICY) or self.target is None:
            self.giving_way_since = None
            return ""
        error = np.abs(state.q[LOAD_BEARING] - self.target[LOAD_BEARING])
        if error.max() <= self.collapse_error:
            self.giving_way_since = None
            return ""
        if self.giving_way_since is None:
            self.giving_way_since = now
        if now - self.giving_way_since <= self.collapse_s:
            return ""
        joint = MOTOR_JOINTS[int(LOAD_BEARING[np.argmax(error)])]
        return (f"collapse: {joint} {error.max():.2f} rad from its target for {now - self.giving_way_since:.2f} s "
                f"(bound {self.collapse_error} rad for {self.collapse_s} s)")

    def command(self, state: RobotState | None, now: float, policy_targets: np.ndarray | None = None) -> MotorCommand | None:
        """This tick's command (None while waiting for state). ``policy_targets`` [29]: used only in POLICY mode."""
        if state is not None and self.mode is Mode.WAIT:
            self.request(Mode.ZERO_TORQUE, now)
        reason = self.watchdog(state, now)
        if reason:
            self.request(Mode.DAMPING, now, reason=reason)
        if self.mode is Mode.WAIT:
            return None
        cmd = MotorCommand()
        if self.mode is Mode.ZERO_TORQUE:
            return cmd
        if self.mode is Mode.DAMPING:
            cmd.kd[:] = DAMPING_KD
            return cmd
        if self.mode is Mode.POLICY:
            cmd.kp[:], cmd.kd[:] = self.kp, self.kd
        else:
            cmd.kp[:], cmd.kd[:] = self.stand_kp, self.stand_kd
        if self.mode is Mode.RAMP:
            alpha = min(1.0, (now - self.mode_since) / RAMP_S)
            cmd.q[:] = (1 - alpha) * self.ramp_from + alpha * self.default_pos
            if alpha >= 1.0:
                self.request(Mode.HOLD, now)
        elif self.mode is Mode.HOLD or policy_targets is None:
            cmd.q[:] = self.default_pos
        else:
            cmd.q[:] = policy_targets
        self.target = cmd.q.copy()
        return cmd
