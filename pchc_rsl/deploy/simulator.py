"""A simulated G1 that is commanded like the real one: the full 29-DoF menagerie model, every motor driven by its
own PD law from the latest rt/lowcmd, clipped to the motor's limit, with optional command latency and jitter and an
optional hold-up band for the start (the robot hangs from a gantry while its motors are off and ramping).

Two PD semantics: recomputed at every physics step (as the G1's motor drivers do, at their own rate), or
``pd_on_arrival``: computed once when a command takes effect and held until the next, as unitree_mujoco's
simulate_python bridge does (its LowCmd handler writes ``tau + kp (q_des - q) + kd (dq_des - dq)`` into ``ctrl``),
from the joint sensors as that bridge reads them: MuJoCo evaluates sensors before it integrates, so after a physics
step they hold the state at the step's start, one step old. With latency, a command takes effect when its delay has
passed, and the torque is computed from the sensors then.

The gantry is a stiff band holding the pelvis at its start pose until ``hold_up_s``, or with ``unitree_band``
unitree_mujoco's elastic band on the torso (elastic_band.py), lowered that many presses of their key 8 and let go
at ``hold_up_s``; with ``band_force_stays`` its last force stays applied, as in their loop without its viewer.

The model is the full 29-DoF menagerie G1, or with ``scene`` another G1 MJCF whose 29 motor actuators and joints
follow unitree_sdk2's motor order, such as unitree_mujoco's ``unitree_robots/g1/scene_29dof.xml``: the same deploy
against that simulator's model and torque semantics, in lockstep, without its process keeping real time."""

from __future__ import annotations

import collections

import mujoco
import numpy as np

from pchc_rsl.deploy.end_point import pose_at, yaw_of
from pchc_rsl.deploy.elastic_band import UnitreeBand
from pchc_rsl.deploy.g1_motors import MOTOR_DEFAULT_POS, MOTOR_EFFORT_LIMIT, MOTOR_JOINTS, NUM_MOTORS
from pchc_rsl.deploy.robot_io import MotorCommand, RobotState
from pchc_rsl.robots.g1.constants import STANDING_HEIGHT
from pchc_rsl.robots.g1.model import build_g1_model

TRACE_PERIOD = 0.02
"""s of simulated time between two samples of the pelvis's pose trace (the policy's period)."""
TRACE_LENGTH = 30000
"""Samples kept: the last 10 minutes."""
FALL_HEIGHT = 0.45
"""Pelvis height (m) under which the robot counts as fallen (the walking task's termination height)."""


def load_scene(path: str) -> mujoco.MjModel:
    """A G1 MJCF in unitree_sdk2's motor order: motor i is a torque actuator on joint MOTOR_JOINTS[i], whose
    position is qpos[7 + i] (after the floating base)."""
    model = mujoco.MjModel.from_xml_path(path)
    if np.any(model.actuator_trntype != mujoco.mjtTrn.mjTRN_JOINT):
        raise ValueError(f"{path}: every actuator must drive a joint (unitree_sdk2's motors)")
    joints = [model.joint(int(model.actuator_trnid[i, 0])) for i in range(model.nu)]
    names = [j.name for j in joints]
    if names != MOTOR_JOINTS or [int(j.qposadr[0]) for j in joints] != list(range(7, 7 + NUM_MOTORS)):
        raise ValueError(f"{path} is not a 29-DoF G1 in unitree_sdk2's motor order: its actuators drive {names[:3]}"
                         f"... ({model.nu}); expected {MOTOR_JOINTS[:3]}... (29), each joint at qpos[7 + i]")
    if not (np.all(model.actuator_biastype == 0) and np.allclose(model.actuator_gainprm[:, 0], 1.0)):
        raise ValueError(f"{path}: its actuators are not torque motors (ctrl = joint torque)")
    return model


class SimulationDiverged(RuntimeError):
    """The physics blew up (MuJoCo resets the state, which would silently restart the clock)."""


class G1Simulator:
    """``apply(cmd, at)`` queues a command, ``step()`` advances one physics step, ``state()`` reads the sensors."""

    def __init__(self, timestep: float = 0.002, latency_s: float = 0.0, jitter_s: float = 0.0,
                 hold_up_s: float = 0.0, seed: int = 0, visual: bool = False, pd_on_arrival: bool = False,
                 scene: str | None = None, unitree_band: int | None = None, band_force_stays: bool = False) -> None:
        if scene is None:
            self.model = build_g1_model(MOTOR_JOINTS, timestep=timestep, torque_control=True, visual=visual)
        else:
            self.model = load_scene(scene)
            self.model.opt.timestep = timestep
        self.data = mujoco.MjData(self.model)
        self.latency_s, self.jitter_s, self.hold_up_s = latency_s, jitter_s, hold_up_s
        self.pd_on_arrival = pd_on_arrival
        self.rng = np.random.default_rng(seed)
        self.pelvis = self.model.body("pelvis").id
        self.torso = self.model.body("torso_link").id
        self.band = None if unitree_band is None else UnitreeBand(unitree_band, hold_up_s, band_force_stays)
        self.data.qpos[2] = STANDING_HEIGHT
        self.data.qpos[7:] = MOTOR_DEFAULT_POS
        mujoco.mj_forward(self.model, self.data)
        self.start_pos = self.data.qpos[:3].copy()
        self.pending: collections.deque[tuple[float, MotorCommand]] = collections.deque()
        self.command = MotorCommand(mode=np.zeros(NUM_MOTORS, dtype=np.uint8))  # motors off until told
        self.fell_at: float | None = None  # sim time the pelvis first dropped below FALL_HEIGHT
        self.damped_at: float | None = None  # sim time the first damping command took effect
        self.distance_at_damping: float | None = None
        self.steps = 0
        self.lowest = np.inf
        self.sensed = (self.data.qpos[7:].copy(), self.data.qvel[6:].copy())
        """Joint positions and velocities as MuJoCo's sensors report them: the state at the last step's start."""
        self.trace: collections.deque = collections.deque(maxlen=TRACE_LENGTH)
        """(time, x, y, heading) of the pelvis every TRACE_PERIOD, for the end point of a walk."""
        self._trace_every = max(1, round(TRACE_PERIOD / timestep))
        self._record_pose()

    @property
    def fell(self) -> bool:
        """The robot fell while it was driven: before any damping command (damping lets it sink on purpose)."""
        return self.fell_at is not None and (self.damped_at is None or self.fell_at < self.damped_at)

    def driven_distance(self) -> float:
        """How far the pelvis went before damping (m): what the policy walked."""
        return self.distance_at_damping if self.distance_at_damping is not None else self.distance_travelled()

    @property
    def time(self) -> float:
        return float(self.data.time)

    def apply(self, command: MotorCommand) -> None:
        """Queue a command; it takes effect after the latency (plus a uniform jitter), in arrival order."""
        delay = self.latency_s + (self.rng.uniform(0.0, self.jitter_s) if self.jitter_s > 0 else 0.0)
        release = self.time + delay
        if self.pending and release < self.pending[-1][0]:
            release = self.pending[-1][0]  # a later command never overtakes an earlier one
        self.pending.append((release, command))

    def step(self) -> None:
        d = self.data
        arrived = False
        while self.pending and self.pending[0][0] <= self.time + 1e-9:
            self.command, arrived = self.pending.popleft()[1], True
            if self.damped_at is None and self.command.is_damping():
                self.damped_at, self.distance_at_damping = self.time, self.distance_travelled()
        if self.pd_on_arrival:
            if arrived:  # else ctrl keeps the torque computed when the last command arrived
                d.ctrl[:] = self.command.torque(*self.sensed, MOTOR_EFFORT_LIMIT)
            self.sensed = (d.qpos[7:].copy(), d.qvel[6:].copy())
        else:
            d.ctrl[:] = self.command.torque(d.qpos[7:], d.qvel[6:], MOTOR_EFFORT_LIMIT)
        if self.band is None:
            d.xfrc_applied[self.pelvis] = self._band() if self.time < self.hold_up_s else 0.0
        elif self.band.on(self.time):
            d.xfrc_applied[self.torso, :3] = self.band.force(self.time, d.qpos[:3], d.qvel[:3])
        elif not self.band.force_stays:
            d.xfrc_applied[self.torso] = 0.0
        mujoco.mj_step(self.model, d)
        if d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0:
            raise SimulationDiverged(f"the G1 simulation diverged at t = {self.time:.3f} s (MuJoCo reset it); "
                                     "a smaller --timestep or softer gains fix this")
        self.steps += 1
        if self.steps % self._trace_every == 0:
            self._record_pose()
        if self.time >= self.hold_up_s:
            if self.damped_at is None:
                self.lowest = min(self.lowest, float(d.qpos[2]))
            if d.qpos[2] < FALL_HEIGHT and self.fell_at is None:
                self.fell_at = self.time

    def _record_pose(self) -> None:
        d = self.data
        self.trace.append((round(self.time, 6), float(d.qpos[0]), float(d.qpos[1]), yaw_of(d.qpos[3:7])))

    def pose_at(self, t: float) -> tuple[float, float, float]:
        """The pelvis's (x, y, heading) at simulated time ``t``, from the trace."""
        return pose_at(np.array(self.trace), t)

    @property
    def min_height_after_release(self) -> float | None:
        """The pelvis's lowest height (m) since the hold-up band let go (before any damping), None before."""
        return round(self.lowest, 4) if self.lowest < np.inf else None

    @property
    def band_force_left(self) -> list[float] | None:
        """unitree_mujoco's band: the force (N, world frame) still on the torso after its release, None before the
        release or without that band."""
        if self.band is None or self.band.on(self.time):
            return None
        return [round(float(f), 2) for f in self.data.xfrc_applied[self.torso, :3]]

    def _band(self) -> np.ndarray:
        """A stiff spring-damper holding the pelvis at its start pose (force and torque, world frame)."""
        d = self.data
        force = 10000.0 * (self.start_pos - d.qpos[:3]) - 1000.0 * d.qvel[:3]
        error = np.zeros(3)
        mujoco.mju_subQuat(error, np.array([1.0, 0, 0, 0]), d.qpos[3:7])
        torque = 200.0 * error - 10.0 * d.qvel[3:6]
        return np.concatenate([force, torque])

    def state(self) -> RobotState:
        d = self.data
        return RobotState(q=d.qpos[7:].copy(), dq=d.qvel[6:].copy(), tau=d.actuator_force.copy(),
                          quat=d.qpos[3:7].copy(), gyro=d.qvel[3:6].copy(), tick=int(round(self.time * 1000)))

    def base_position(self) -> np.ndarray:
        return self.data.qpos[:3].copy()

    def distance_travelled(self) -> float:
        """Horizontal distance of the pelvis from where it started (m)."""
        return float(np.linalg.norm(self.data.qpos[:2] - self.start_pos[:2]))
