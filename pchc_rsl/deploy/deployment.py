"""One code path from a policy file to a G1, whatever carries the messages: in-process MuJoCo (lockstep, no DDS),
the MuJoCo DDS bridge on loopback, or the real robot. Each control period: read the latest state, apply the
operator's input, let the safety state machine decide the command (the policy's only in POLICY mode), send it."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from pchc_rsl.deploy.command_sequence import CommandSequence
from pchc_rsl.deploy.end_point import end_point_report, in_start_frame, integrate_twist, pose_at, yaw_of
from pchc_rsl.deploy.fixed_rate import FixedRateLoop
from pchc_rsl.deploy.fresh_states import FreshStates
from pchc_rsl.deploy.g1_motors import MOTOR_DEFAULT_POS, MOTOR_HOLD_KD, MOTOR_HOLD_KP, MOTOR_JOINTS
from pchc_rsl.deploy.live_controls import (PREFERENCE_STEP, SPEED_STEP, YAW_STEP, Command, Preference, RemoteEdges,
                                           stick_command)
from pchc_rsl.deploy.policy_step import PolicyStep
from pchc_rsl.deploy.robot_io import MotorCommand, Remote, RobotState
from pchc_rsl.deploy.safety import Mode, SafetyStateMachine
from pchc_rsl.deploy.simulator import G1Simulator
from pchc_rsl.deploy.stand_still import StandStill

NO_STATE_TIMEOUT_S = 3.0
STEERING_KEYS = {"w": (0, SPEED_STEP), "x": (0, -SPEED_STEP), "a": (1, SPEED_STEP), "d": (1, -SPEED_STEP),
                 "q": (2, YAW_STEP), "e": (2, -YAW_STEP)}
"""key -> (command component, change): a and q go left (positive lateral speed and yaw rate, as in the G1's frame)."""


class NoLowState(RuntimeError):
    """No rt/lowstate arrived in time."""


class InProcessRobot:
    """The simulator driven in lockstep: each tick advances the physics by one control period (no wall clock). The
    newest command is handed to the simulator again at ``lowcmd_hz`` within the period, as the DDS stream writes it
    (which matters where the simulator computes the torque when a command arrives)."""

    def __init__(self, sim: G1Simulator, period_s: float, lowcmd_hz: float | None = None) -> None:
        self.sim, self.period = sim, period_s
        self.substeps = max(1, round(period_s / sim.model.opt.timestep))
        self.lowcmd_period = 1.0 / lowcmd_hz if lowcmd_hz else period_s
        self.sent = self.commands = 0
        self.states = FreshStates()
        self.latest: MotorCommand | None = None
        self.next_lowcmd = 0.0
        self.loop = None

    def now(self) -> float:
        return self.sim.time

    def read(self) -> RobotState:
        state = self.sim.state()
        state.received_at = self.sim.time
        self.states.add(state)
        return state

    @property
    def received(self) -> int:
        return self.states.received

    def send(self, cmd: MotorCommand) -> None:
        self.latest = cmd
        self.commands += 1
        self.sim.apply(cmd)
        self.sent += 1
        self.next_lowcmd = self.sim.time + self.lowcmd_period

    def wait_tick(self) -> None:
        for _ in range(self.substeps):
            if self.latest is not None and self.sim.time >= self.next_lowcmd - 1e-9:
                self.sim.apply(self.latest)
                self.sent += 1
                self.next_lowcmd += self.lowcmd_period
            self.sim.step()


class WallClockRobot:
    """A DDS robot (bridge or real) paced by a fixed-rate loop on the monotonic clock."""

    def __init__(self, dds, period_s: float) -> None:
        self.dds = dds
        self.loop = FixedRateLoop(period_s)

    def now(self) -> float:
        return time.monotonic()

    def read(self) -> RobotState | None:
        return self.dds.read()

    def send(self, cmd: MotorCommand) -> None:
        self.dds.send(cmd)

    def wait_tick(self) -> None:
        self.loop.wait()

    @property
    def received(self) -> int:
        return self.dds.received

    @property
    def states(self) -> FreshStates:
        return self.dds.states

    @property
    def sent(self) -> int:
        return self.dds.sent

    @property
    def commands(self) -> int:
        return self.dds.commands

    @property
    def stream(self):
        return getattr(self.dds, "stream", None)


@dataclass
class AutoSequence:
    """The whole start without keys (--sim, tests): zero torque, ramp, hold, then the policy until the end. The hold
    lasts at least ``hold_s``; the policy is asked for then and starts once the robot stands still."""

    zero_torque_s: float = 0.5
    hold_s: float = 1.0

    def due(self, machine: SafetyStateMachine, now: float) -> Mode | None:
        """The mode to ask for now, if any."""
        since = now - machine.mode_since
        if machine.mode is Mode.ZERO_TORQUE and since >= self.zero_torque_s:
            return Mode.RAMP
        if machine.mode is Mode.HOLD and since >= self.hold_s:
            return Mode.POLICY
        return None


@dataclass
class DeployLog:
    events: list = field(default_factory=list)
    trajectory: list = field(default_factory=list)  # (time since policy start, q of the policy joints)
    commands: list = field(default_factory=list)  # (time since policy start, command) at each change
    policy_states: list = field(default_factory=list)  # the states the policy started and (so far) ended with


class Deployment:
    def __init__(self, policy: PolicyStep, robot, preference, command=(0.0, 0.0, 0.0),
                 auto: AutoSequence | None = None, inputs: list = (), log=print,
                 sequence: CommandSequence | None = None, wait_still: bool = True) -> None:
        """``command``: (forward, lateral, yaw rate) to start with; ``inputs``: sources with ``pending()`` -> keys
        ('s', 'p', ...) or (name, value) settings: the terminal's KeyReader, the browser console; ``sequence``: the
        command over time from the policy's start, set as the console sets it (so clipped to the same ranges);
        ``wait_still``: the policy, asked for in HOLD, starts once the robot stands still (False: at once)."""
        self.policy, self.robot, self.auto, self.inputs, self.log = policy, robot, auto, list(inputs), log
        joints = policy.joints
        kp, kd = MOTOR_HOLD_KP.copy(), MOTOR_HOLD_KD.copy()
        kp[joints.motor_index], kd[joints.motor_index] = policy.kp, policy.kd
        for name, (held_kp, held_kd) in policy.meta.get("held_joints", {}).items():  # as the policy trained them
            kp[MOTOR_JOINTS.index(name)], kd[MOTOR_JOINTS.index(name)] = held_kp, held_kd
        self.default_pos = joints.to_motors(policy.default_pos, MOTOR_DEFAULT_POS)
        self.safety = SafetyStateMachine(kp, kd, self.default_pos, joints.motor_index, policy.joint_range)
        self.preference = Preference(preference, policy.objective_names)
        self.command = Command(policy.command_ranges, command)
        self.remote = RemoteEdges()
        self.sequence, self._row = sequence, None
        self.sticks_active = False
        self._stick_shown, self._stick_shown_at = "", -1.0
        self.record = DeployLog()
        self.quit_requested = False
        self.policy_since: float | None = None
        self.policy_until: float | None = None
        self.stand_still = StandStill() if wait_still else None
        self.policy_asked_at: float | None = None  # a request for the policy waiting for the robot to stand still
        self.waited_s = 0.0  # how long the policy's start waited for it
        self.started = robot.now()
        self._shown = -1.0

    # ------------------------------------------------------------------ input
    def _operator(self, state: RobotState | None, now: float) -> None:
        actions = [action for source in self.inputs for action in source.pending()]
        sticks = None
        if state is not None:
            remote = Remote.parse(state.remote)
            pressed = self.remote.pressed(remote.buttons)
            names = {"start": "s", "A": "p", "select": " ", "B": " ", "L1": "[", "R1": "]", "up": "w", "down": "x"}
            actions += [names[b] for b in pressed if b in names]
            sticks = stick_command(remote.lx, remote.ly, remote.rx)
        for key in actions:
            self._act(key, state, now)
        if sticks is not None:
            self._steer(sticks, now)
        if self.auto is not None:
            due = self.auto.due(self.safety, now)
            if due is Mode.RAMP:
                self.safety.request(Mode.RAMP, now, state)
            elif due is Mode.POLICY and self.policy_asked_at is None:
                self._ask_policy(state, now)
        if self.policy_asked_at is not None:
            self._start_when_still(state, now)
        if now - self._shown >= 0.25:
            command = self.command.value.copy() if self.policy.uses_command else None
            reason = (f"waiting for the robot to stand still: {self.stand_still}" if self.policy_asked_at is not None
                      else self.safety.reason)
            for source in self.inputs:
                if hasattr(source, "show"):
                    source.show(self.safety.mode.value, reason, self.preference.value, command)
            self._shown = now

    def _ask_policy(self, state: RobotState | None, now: float) -> None:
        """Start the policy, in HOLD once the robot stands still: until then the request is kept (said once on the
        console) and the policy starts by itself when it does."""
        if self.stand_still is None or self.safety.mode is not Mode.HOLD or self.stand_still.still:
            self.safety.request(Mode.POLICY, now, state)
        elif self.policy_asked_at is None:
            self.policy_asked_at = now
            self.log(f"waiting for the robot to stand still: {self.stand_still}")

    def _start_when_still(self, state: RobotState | None, now: float) -> None:
        if self.safety.mode is not Mode.HOLD:  # damped meanwhile: the request goes with the hold
            self.policy_asked_at = None
        elif self.stand_still.still:
            self.waited_s = now - self.policy_asked_at
            self.policy_asked_at = None
            self.log(f"the robot stands still after {self.waited_s:.1f} s: {self.stand_still}")
            self.safety.request(Mode.POLICY, now, state)

    def _steer(self, sticks: tuple[float, float, float], now: float) -> None:
        """The remote's sticks own the command while any is off centre; letting them all go stops the robot. The
        command a stick sets is shown at most twice a second (it changes at every tick while the stick moves)."""
        if any(sticks):
            for note in self.command.from_sticks(*sticks):
                self.log(note)
            self.sticks_active = True
            if str(self.command) != self._stick_shown and now - self._stick_shown_at >= 0.5:
                self._stick_shown, self._stick_shown_at = str(self.command), now
                self._show_change()
        elif self.sticks_active:
            self.sticks_active = False
            self.command.stop()
            self._show_change()

    def _show_change(self) -> None:
        self.log(f"{self.preference}" + (f", {self.command}" if self.policy.uses_command else ""))

    def _act(self, key, state: RobotState | None, now: float) -> None:
        before = (str(self.preference), str(self.command))
        notes = []
        if isinstance(key, tuple):  # a setting from the browser console
            name, value = key
            if name == "preference":
                self.preference.value = np.asarray(value, float)
            elif name == "command":
                notes = [self.command.set(k, float(v)) for k, v in enumerate(value)]
        elif key == "s":
            self.safety.request(Mode.RAMP, now, state)
        elif key == "p":
            self._ask_policy(state, now)
        elif key == " ":
            self.safety.request(Mode.DAMPING, now, reason="operator")
        elif key == "Q":
            self.safety.request(Mode.DAMPING, now, reason="quit")
            self.quit_requested = True
        elif key in ("[", "]"):
            self.preference.towards(0 if key == "[" else len(self.preference.value) - 1)
        elif key.isdigit() and 0 < int(key) <= len(self.preference.value):
            self.preference.selected = int(key) - 1
        elif key in ("+", "-"):
            self.preference.towards(self.preference.selected, PREFERENCE_STEP if key == "+" else -PREFERENCE_STEP)
        elif key in STEERING_KEYS:
            component, delta = STEERING_KEYS[key]
            notes = [self.command.change(component, delta)]
        elif key == "z":
            self.command.stop()
        for note in notes:
            if note:
                self.log(note)
        after = (str(self.preference), str(self.command))
        if after != before:
            self._show_change()

    # ------------------------------------------------------------------ one control period
    def tick(self) -> None:
        now = self.robot.now()
        state = self.robot.read()
        mode_before = self.safety.mode
        self._watch_stillness(state, now)
        self._operator(state, now)
        targets = None
        if self.safety.mode is Mode.POLICY:
            if self.policy_since is None:
                self.policy_since = now
                self._follow_sequence(state, now)
                self.policy.reset(state, self.command.value)
                self.record.policy_states = [state, state]
            else:
                self._follow_sequence(state, now)
                self.record.policy_states[1] = state
            self._log_command(now - self.policy_since)
            q = self.policy(state, self.preference.value, self.command.value)
            targets = self.policy.joints.to_motors(q, self.default_pos)
            self.record.trajectory.append((now - self.policy_since, self.policy.joints.to_policy(state.q)))
        cmd = self.safety.command(state, now, targets)
        if mode_before is Mode.POLICY and self.safety.mode is not Mode.POLICY:
            self.policy_until = now
        if self.safety.mode is not mode_before:
            reason = f" ({self.safety.reason})" if self.safety.reason else ""
            self.log(f"{self.safety.mode.value}{reason}")
            self.record.events.append((round(now - self.started, 3), self.safety.mode.name, self.safety.reason))
            if self.stand_still is not None:
                self.stand_still.reset()
                self._watch_stillness(state, now)  # the state HOLD began with is its first sample
        if cmd is not None:
            self.robot.send(cmd)

    def _watch_stillness(self, state: RobotState | None, now: float) -> None:
        """In HOLD, each state is a sample of whether the robot stands still."""
        if self.stand_still is not None and self.safety.mode is Mode.HOLD and state is not None:
            self.stand_still.update(now, state.gyro, state.projected_gravity())

    def _follow_sequence(self, state: RobotState, now: float) -> None:
        """The command sequence's row for this moment, set once when its row begins (keys may change it between)."""
        if self.sequence is None:
            return
        row = self.sequence.at(now - self.policy_since)
        if row is not self._row:
            self._row = row
            self._act(("command", row.command), state, now)

    def _log_command(self, t: float) -> None:
        value = tuple(float(v) for v in self.command.value)
        if not self.record.commands or self.record.commands[-1][1] != value:
            self.record.commands.append((round(t, 4), value))

    def commanded_end_point(self) -> tuple[float, float, float]:
        """Where the commands the policy was given lead (x, y, heading from its start pose), over its time."""
        end = (self.policy_until or self.robot.now()) - self.policy_since
        times = [t for t, _ in self.record.commands] + [end]
        return integrate_twist([(times[i + 1] - t, command) for i, (t, command) in enumerate(self.record.commands)])

    def run(self, seconds: float | None = None, no_state_hint: str = "",
            no_state_timeout: float = NO_STATE_TIMEOUT_S) -> None:
        """Tick until ``seconds`` of policy (or of the whole run without an auto sequence), a quit or Ctrl-C; then
        damp for half a second so the robot is left safe."""
        start = self.robot.now()
        try:
            while not self.quit_requested:
                self.tick()
                now = self.robot.now()
                if self.safety.mode is Mode.WAIT and now - start > no_state_timeout:
                    raise NoLowState(f"no rt/lowstate within {no_state_timeout:.0f} s{no_state_hint}")
                if seconds is not None:
                    since = self.policy_since if self.auto is not None else start
                    if since is not None and now - since >= seconds:
                        break
                    if self.safety.mode is Mode.DAMPING and self.auto is not None:
                        break
                self.robot.wait_tick()
        except KeyboardInterrupt:
            if self.safety.mode is Mode.POLICY:
                self.policy_until = self.robot.now()
            self.safety.request(Mode.DAMPING, self.robot.now(), reason="Ctrl-C")
        finally:
            self._damp_out()

    def _damp_out(self, seconds: float = 0.5) -> None:
        if self.safety.mode is Mode.WAIT:
            return
        now = self.robot.now()
        if self.safety.mode is not Mode.DAMPING:
            if self.safety.mode is Mode.POLICY:
                self.policy_until = now
            self.safety.request(Mode.DAMPING, now, reason=self.safety.reason or "end of run")
            self.log(f"damping ({self.safety.reason})")
        end = now + seconds
        while self.robot.now() < end:
            cmd = self.safety.command(self.robot.read(), self.robot.now())
            if cmd is not None:
                self.robot.send(cmd)
            self.robot.wait_tick()

    def end_point(self, pose_trace=None) -> dict:
        """The end point against the commanded one; where the pelvis went comes from a simulator's ``pose_trace``
        [T, 4] (time, x, y, heading) at the LowState ticks the policy started and ended with (a robot's LowState
        carries no position: then only the IMU's heading change)."""
        first, last = self.record.policy_states
        ticks = [int(first.tick), int(last.tick)]
        reached = None
        if pose_trace is not None and len(pose_trace):
            reached = in_start_frame(pose_at(pose_trace, ticks[0] / 1000), pose_at(pose_trace, ticks[1] / 1000))
        heading = math.remainder(yaw_of(last.quat) - yaw_of(first.quat), 2 * math.pi)
        return end_point_report(self.commanded_end_point(), reached, heading) | {"ticks": ticks}

    def report(self, pose_trace=None) -> dict:
        out = {"task": self.policy.task, "final_mode": self.safety.mode.name, "reason": self.safety.reason,
               "preference": [round(float(x), 4) for x in self.preference.value],
               "policy_seconds": (round((self.policy_until or self.robot.now()) - self.policy_since, 3)
                                  if self.policy_since is not None else 0),
               "messages_received": int(self.robot.received), "messages_sent": int(self.robot.sent),
               "commands": int(getattr(self.robot, "commands", 0)), "lowstate": self.robot.states.summary(),
               "events": self.record.events,
               "stand_still": None if self.stand_still is None else {
                   "waited_s": round(self.waited_s, 3), "gyro_bound": self.stand_still.gyro_bound,
                   "tilt_rate_bound": self.stand_still.tilt_rate_bound, "window_s": self.stand_still.window_s}}
        if self.record.commands and self.policy.uses_command:
            out["policy_commands"] = [[t, *command] for t, command in self.record.commands]  # at each change
            out["end_point"] = self.end_point(pose_trace)
        if self.record.trajectory:
            _, q = policy_trajectory(self.record)
            out["policy_joint_mean"] = [round(float(x), 4) for x in q.mean(0)]  # the posture, to compare runs
            out["policy_joint_std"] = [round(float(x), 4) for x in q.std(0)]  # how much each joint swings
        if self.robot.loop is not None:
            out["loop"] = self.robot.loop.summary()
        if getattr(self.robot, "stream", None) is not None:
            out["lowcmd"] = self.robot.stream.summary()
        return out


def policy_trajectory(record: DeployLog) -> tuple[np.ndarray, np.ndarray]:
    """(times [T], joint positions [T, J]) of the policy phase."""
    if not record.trajectory:
        return np.zeros(0), np.zeros((0, 0))
    times, q = zip(*record.trajectory)
    return np.array(times), np.stack(q)
