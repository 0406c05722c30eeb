"""pchc-deploy's parts: the CRC a G1 checks, the joint map, the remote's bytes, the observation against the training
env's, the safety state machine and its watchdog, the fixed-rate loop, one DDS run on loopback, and bad input."""

from __future__ import annotations

import json
import math
import random
import struct
import subprocess
import sys

import numpy as np
import pytest

from pchc_rsl.deploy.g1_motors import MOTOR_DEFAULT_POS, MOTOR_JOINTS, NUM_MOTORS, JointMap
from pchc_rsl.deploy.robot_io import MotorCommand, Remote, RobotState
from pchc_rsl.deploy.safety import DAMPING_KD, RAMP_S, Mode, SafetyStateMachine
from pchc_rsl.robots.g1.constants import WALK_JOINTS
from tool_loader import load_tool

WALK_ONNX = "policies/g1_walk.onnx"


def sdk_available() -> bool:
    try:
        import unitree_sdk2py  # noqa: F401

        return True
    except ImportError:
        return False


def g1_available() -> bool:
    from test_g1_env import g1_available as available

    return available()


needs_sdk = pytest.mark.skipif(not sdk_available(), reason="unitree_sdk2py missing (pip install -e \".[deploy]\")")
needs_g1 = pytest.mark.skipif(not g1_available(), reason="G1 model unavailable (set MENAGERIE_ROOT)")


STEERING_RANGES = {"lin_vel_x": [-0.5, 1.0], "lin_vel_y": [-0.5, 0.5], "ang_vel_z": [-1.0, 1.0]}


@pytest.fixture(scope="module")
def steering_onnx(tmp_path_factory) -> str:
    """The shipped walker's network with the metadata of a policy trained on all three commands (the walking
    config's ranges): what the steering needs to be tested, whatever the network learned."""
    import onnx

    from pchc_rsl.export.metadata import METADATA_KEY

    model = onnx.load(WALK_ONNX)
    entry = next(p for p in model.metadata_props if p.key == METADATA_KEY)
    meta = json.loads(entry.value)
    meta["command_ranges"] = STEERING_RANGES
    entry.value = json.dumps(meta)
    path = tmp_path_factory.mktemp("steering") / "steering.onnx"
    onnx.save(model, str(path))
    return str(path)


def walker_with_ranges(folder, ranges: dict | None) -> str:
    """The shipped walker's network with other command ranges in its metadata (None: no ranges at all, as in files
    exported before the key existed)."""
    import onnx

    from pchc_rsl.export.metadata import METADATA_KEY

    model = onnx.load(WALK_ONNX)
    entry = next(p for p in model.metadata_props if p.key == METADATA_KEY)
    meta = json.loads(entry.value)
    meta.pop("command_ranges", None)
    if ranges is not None:
        meta["command_ranges"] = ranges
    entry.value = json.dumps(meta)
    path = folder / "walker.onnx"
    onnx.save(model, str(path))
    return str(path)


FORWARD_ONLY = {"lin_vel_x": [0.0, 1.0], "lin_vel_y": [0.0, 0.0], "ang_vel_z": [0.0, 0.0]}


@pytest.fixture(scope="module")
def forward_only_onnx(tmp_path_factory) -> str:
    """A walker trained on forward commands only (lateral and yaw ranges 0..0)."""
    return walker_with_ranges(tmp_path_factory.mktemp("forward"), FORWARD_ONLY)


def standing_state(q=None, received_at: float = 0.0) -> RobotState:
    return RobotState(q=MOTOR_DEFAULT_POS.copy() if q is None else q, dq=np.zeros(NUM_MOTORS), tau=np.zeros(NUM_MOTORS),
                      quat=np.array([1.0, 0, 0, 0]), gyro=np.zeros(3), received_at=received_at)


# ---------------------------------------------------------------------------------------------- CRC and messages
def unitree_crc32(words: list[int]) -> int:
    """Unitree's crc32_core (polynomial 0x04C11DB7, MSB first, initial 0xFFFFFFFF, no final xor), written out."""
    crc, poly = 0xFFFFFFFF, 0x04C11DB7
    for word in words:
        bit = 1 << 31
        for _ in range(32):
            crc = ((crc << 1) & 0xFFFFFFFF) ^ poly if crc & 0x80000000 else (crc << 1) & 0xFFFFFFFF
            if word & bit:
                crc ^= poly
            bit >>= 1
    return crc


@needs_sdk
def test_lowcmd_crc_is_the_one_a_g1_checks():
    from pchc_rsl.deploy.sdk import lowcmd_message

    cmd = MotorCommand()
    cmd.q[:] = np.linspace(-1, 1, NUM_MOTORS)
    cmd.kp[:], cmd.kd[:], cmd.tau[3] = 40.0, 2.5, 1.25
    msg = lowcmd_message(cmd, mode_machine=5)
    # hg LowCmd as the robot packs it: mode_pr, mode_machine, 2 pad, 35 x (mode, 3 pad, q dq tau kp kd, reserve),
    # reserve[4], crc
    values = [msg.mode_pr, msg.mode_machine]
    for m in msg.motor_cmd:
        values += [m.mode, m.q, m.dq, m.tau, m.kp, m.kd, m.reserve]
    packed = struct.pack("<2B2x" + "B3x5fI" * 35 + "5I", *values, *msg.reserve, msg.crc)
    words = struct.unpack(f"<{len(packed) // 4}I", packed)[:-1]  # every word but the CRC itself
    assert msg.crc == unitree_crc32(list(words))
    assert msg.mode_machine == 5 and msg.motor_cmd[3].tau == pytest.approx(1.25)
    assert [m.mode for m in msg.motor_cmd] == [1] * NUM_MOTORS + [0] * 6


@needs_sdk
def test_numpy_encodings_are_the_sdks_bytes():
    """What goes on the wire (the CDR sample) and the CRC equal cyclonedds's serializer and the SDK's CRC, both ways
    and for both messages; a sample of another size is refused in one line."""
    from unitree_sdk2py.utils.crc import CRC

    from pchc_rsl.deploy.sdk import command_of_packed, lowcmd_message, lowstate_message
    from pchc_rsl.deploy.wire_format import crc32, lowcmd_from_cdr, lowstate_from_cdr

    rng = np.random.default_rng(0)
    cmd = MotorCommand(q=rng.normal(size=NUM_MOTORS), dq=rng.normal(size=NUM_MOTORS),
                       kp=rng.uniform(0, 100, NUM_MOTORS), kd=rng.uniform(0, 5, NUM_MOTORS),
                       tau=rng.normal(size=NUM_MOTORS))
    msg = lowcmd_message(cmd, mode_machine=5, mode_pr=1)
    assert msg.serialize() == type(msg).serialize(msg)  # cyclonedds's own encoding of the same fields
    assert msg.crc == CRC().Crc(msg)
    back = lowcmd_from_cdr(msg.serialize())
    assert crc32(back) == msg.crc
    np.testing.assert_allclose(command_of_packed(back).kp, cmd.kp, rtol=1e-6)
    state = standing_state()
    state.q = rng.normal(size=NUM_MOTORS)
    state.tick, state.remote = 4321, Remote(frozenset({"B"}), rx=0.5).encode()
    msg = lowstate_message(state, 5)
    assert msg.serialize() == type(msg).serialize(msg) and msg.crc == CRC().Crc(msg)
    assert crc32(lowstate_from_cdr(msg.serialize())) == msg.crc
    with pytest.raises(ValueError, match="LowState of 1000 bytes.*has 2088"):
        lowstate_from_cdr(lowcmd_message(cmd, 5).serialize())


@needs_sdk
def test_lowstate_round_trips_with_the_remote():
    from pchc_rsl.deploy.sdk import lowstate_message, state_of_packed
    from pchc_rsl.deploy.wire_format import lowstate_from_cdr

    state = standing_state()
    state.quat = np.array([0.9, 0.1, -0.2, 0.3]) / np.linalg.norm([0.9, 0.1, -0.2, 0.3])
    state.gyro = np.array([0.5, -0.25, 1.0])
    state.remote = Remote(frozenset({"A", "L1"}), ly=0.5).encode()
    back = state_of_packed(lowstate_from_cdr(lowstate_message(state, 5).serialize()), received_at=1.0)
    np.testing.assert_allclose(back.q, state.q, atol=1e-6)
    np.testing.assert_allclose(back.quat, state.quat, atol=1e-6)
    np.testing.assert_allclose(back.gyro, state.gyro, atol=1e-6)
    assert back.mode_machine == 5 and Remote.parse(back.remote).buttons == {"A", "L1"}


# ---------------------------------------------------------------------------------------------- joints, remote
def test_joint_map_goes_by_name_and_round_trips():
    shuffled = list(reversed(WALK_JOINTS))
    joints = JointMap(shuffled)
    motor_values = np.arange(NUM_MOTORS, dtype=float)
    policy_values = joints.to_policy(motor_values)
    assert [MOTOR_JOINTS[int(v)] for v in policy_values] == shuffled
    back = joints.to_motors(policy_values, fill=np.full(NUM_MOTORS, -1.0))
    driven = [MOTOR_JOINTS.index(j) for j in shuffled]
    assert (back[driven] == motor_values[driven]).all()
    assert (np.delete(back, driven) == -1.0).all() and len(joints.held) == 9  # waist 3, wrists 6


def test_joint_map_refuses_joints_a_g1_does_not_have():
    with pytest.raises(ValueError, match="left_toe_joint"):
        JointMap(["left_hip_pitch_joint", "left_toe_joint"])
    with pytest.raises(ValueError, match="twice"):
        JointMap(["left_knee_joint", "left_knee_joint"])


def test_remote_bytes_follow_unitrees_layout():
    data = bytearray(40)
    data[2:4] = (0x0100 | 0x0001 | 0x8000).to_bytes(2, "little")  # A, R1, left
    data[4:8] = struct.pack("<f", 0.25)  # lx
    data[20:24] = struct.pack("<f", -0.75)  # ly
    remote = Remote.parse(bytes(data))
    assert remote.buttons == {"A", "R1", "left"}
    assert remote.lx == 0.25 and remote.ly == -0.75 and remote.rx == 0.0
    assert Remote.parse(remote.encode()) == remote


# ---------------------------------------------------------------------------------------------- safety
def test_no_policy_command_before_the_ramp_has_finished():
    machine = SafetyStateMachine()
    state = standing_state(q=np.zeros(NUM_MOTORS))
    assert machine.command(None, 0.0) is None  # nothing goes out before a state arrives
    assert machine.command(state, 0.0).kp.max() == 0.0  # zero torque
    assert not machine.request(Mode.POLICY, 0.1, state)
    assert not machine.request(Mode.RAMP, 0.5, state)  # from a state 0.5 s old: refused
    state.received_at = 0.5
    assert machine.request(Mode.RAMP, 0.5, state)
    policy_targets = np.full(NUM_MOTORS, 0.3)
    for now in np.arange(0.5, 0.5 + RAMP_S, 0.02):
        assert not machine.request(Mode.POLICY, now, state)
        cmd = machine.command(standing_state(q=np.zeros(NUM_MOTORS), received_at=now), now, policy_targets)
        alpha = (now - 0.5) / RAMP_S
        np.testing.assert_allclose(cmd.q, alpha * MOTOR_DEFAULT_POS, atol=1e-9)  # on the straight line, never 0.3
    cmd = machine.command(standing_state(received_at=2.5), 2.5)
    assert machine.mode is Mode.HOLD and np.allclose(cmd.q, MOTOR_DEFAULT_POS)
    assert machine.request(Mode.POLICY, 2.6, state)
    cmd = machine.command(standing_state(received_at=2.6), 2.6, policy_targets)
    assert np.allclose(cmd.q, 0.3)


class FakeRobot:
    """A robot in the default pose whose state stops arriving at ``silent_after`` (s), its IMU reading ``gyro(t)``
    (still: zero); records what was sent and when."""

    def __init__(self, silent_after: float = 1e9, interrupt_at: float = 1e9, gyro=lambda t: np.zeros(3)) -> None:
        from pchc_rsl.deploy.fresh_states import FreshStates

        self.t, self.silent_after, self.interrupt_at, self.gyro = 0.0, silent_after, interrupt_at, gyro
        self.sent, self.loop, self.states = [], None, FreshStates()
        self.last_state: RobotState | None = None
        self.remote = Remote()  # what the operator holds on the G1's remote

    @property
    def received(self) -> int:
        return self.states.received

    def now(self):
        return self.t

    def read(self):
        if self.t <= self.silent_after:
            self.last_state = standing_state(received_at=self.t)
            self.last_state.gyro = np.asarray(self.gyro(self.t), float)
            self.last_state.remote = self.remote.encode()
            self.states.add(self.last_state)
        return self.last_state

    def send(self, cmd):
        self.sent.append((self.t, cmd))

    def wait_tick(self):
        self.t = round(self.t + 0.02, 6)
        if self.t >= self.interrupt_at:
            self.interrupt_at = 1e9
            raise KeyboardInterrupt


def fake_deployment(robot, policy_file: str = WALK_ONNX, log=lambda *_: None):
    from pchc_rsl.deploy.deployment import AutoSequence, Deployment
    from pchc_rsl.deploy.policy_step import PolicyStep

    run = Deployment(PolicyStep(policy_file), robot, [0.5, 0.5], (0.5, 0.0, 0.0), AutoSequence(), log=log)
    run.safety.collapse_s = np.inf  # the fake robot does not follow its targets; the collapse check has its own tests
    return run


def is_damping(cmd: MotorCommand) -> bool:
    return cmd.kp.max() == 0.0 and np.allclose(cmd.kd, DAMPING_KD)


def test_hold_and_ramp_use_the_standing_gains_and_the_policy_its_own():
    from pchc_rsl.deploy.g1_motors import MOTOR_STAND_KD, MOTOR_STAND_KP

    machine = SafetyStateMachine(kp=np.full(NUM_MOTORS, 40.0), kd=np.full(NUM_MOTORS, 1.0))
    machine.command(standing_state(), 0.0)
    machine.request(Mode.RAMP, 0.1, standing_state(received_at=0.1))
    ramp = machine.command(standing_state(received_at=0.2), 0.2)
    hold = machine.command(standing_state(received_at=2.2), 2.2)
    assert machine.mode is Mode.HOLD
    for cmd in (ramp, hold):
        assert cmd.kp.tolist() == MOTOR_STAND_KP.tolist() and cmd.kd.tolist() == MOTOR_STAND_KD.tolist()
    assert MOTOR_STAND_KP[[3, 9, 4, 10]].tolist() == [400.0, 400.0, 300.0, 300.0]  # knees, ankle pitch
    machine.request(Mode.POLICY, 2.3, standing_state())
    policy = machine.command(standing_state(received_at=2.3), 2.3, np.zeros(NUM_MOTORS))
    assert policy.kp.tolist() == [40.0] * NUM_MOTORS


@pytest.mark.parametrize("mode", [Mode.HOLD, Mode.POLICY])
def test_a_collapse_that_does_not_tilt_damps(mode):
    """A knee sinking 0.8 rad from its target with the pelvis level: not yet within COLLAPSE_S, damped after it;
    a short excursion (a step) is not a collapse."""
    from pchc_rsl.deploy.safety import COLLAPSE_ERROR, COLLAPSE_S

    machine = SafetyStateMachine()
    machine.command(standing_state(), 0.0)
    machine.request(Mode.RAMP, 0.0, standing_state())
    machine.command(standing_state(received_at=RAMP_S), RAMP_S)
    if mode is Mode.POLICY:
        machine.request(Mode.POLICY, RAMP_S, standing_state())
    sunk = MOTOR_DEFAULT_POS.copy()
    sunk[MOTOR_JOINTS.index("right_knee_joint")] += COLLAPSE_ERROR + 0.2
    t0 = RAMP_S + 0.02
    for t in np.arange(t0, t0 + COLLAPSE_S - 0.05, 0.02):  # shorter than the bound
        machine.command(standing_state(sunk, received_at=t), t, MOTOR_DEFAULT_POS)
    assert machine.mode is mode
    t = t + 0.02
    machine.command(standing_state(received_at=t), t, MOTOR_DEFAULT_POS)  # back on target: the timer restarts
    for t in np.arange(t + 0.02, t + COLLAPSE_S + 0.1, 0.02):
        machine.command(standing_state(sunk, received_at=t), t, MOTOR_DEFAULT_POS)
    assert machine.mode is Mode.DAMPING and machine.reason.startswith("collapse: right_knee_joint")


def test_a_tilt_in_hold_damps():
    machine = SafetyStateMachine()
    machine.command(standing_state(), 0.0)
    machine.request(Mode.RAMP, 0.0, standing_state())
    machine.command(standing_state(received_at=RAMP_S), RAMP_S)
    tilted = standing_state(received_at=RAMP_S + 0.02)
    tilted.quat = np.array([np.cos(0.5), 0.0, np.sin(0.5), 0.0])  # 57 degrees about y
    machine.command(tilted, RAMP_S + 0.02)
    assert machine.mode is Mode.DAMPING and machine.reason == "tilt 57 degrees"


def test_the_lowcmd_stream_writes_the_newest_command_and_damps_a_stalled_loop():
    import time

    from pchc_rsl.deploy.lowcmd_stream import LowCmdStream

    written = []
    stream = LowCmdStream(written.append, rate_hz=500.0, stall_s=0.1)
    first, second = MotorCommand(), MotorCommand()
    first.kp[:], second.kp[:] = 10.0, 20.0
    stream.set(first)
    time.sleep(0.03)
    stream.set(second)
    time.sleep(0.05)
    assert written[0] is first and written[-1] is second
    time.sleep(0.3)  # the control loop is silent for longer than stall_s
    stream.close()
    assert written[-1].is_damping() and stream.stalls == 1
    switch = next(i for i, cmd in enumerate(written) if cmd is second)
    assert switch >= 1 and all(cmd is first for cmd in written[:switch])


@needs_g1
def test_pd_on_arrival_holds_the_torque_of_arrival():
    """unitree_mujoco's semantics: the torque is computed when the command takes effect, from the joint sensors as
    MuJoCo left them (the state at the start of the last physics step), and held; otherwise it is recomputed at
    every step from the state now."""
    from pchc_rsl.deploy.g1_motors import MOTOR_EFFORT_LIMIT
    from pchc_rsl.deploy.simulator import G1Simulator

    def torque(cmd, q, dq):
        return np.clip(30.0 * (cmd.q - q) + 1.0 * (0.0 - dq), -MOTOR_EFFORT_LIMIT, MOTOR_EFFORT_LIMIT)

    for on_arrival in (True, False):
        sim = G1Simulator(hold_up_s=10.0, pd_on_arrival=on_arrival)
        cmd = MotorCommand(q=MOTOR_DEFAULT_POS + 0.2, kp=np.full(NUM_MOTORS, 30.0), kd=np.full(NUM_MOTORS, 1.0))
        at_arrival = torque(cmd, sim.data.qpos[7:].copy(), sim.data.qvel[6:].copy())
        sim.apply(cmd)
        sim.step()
        np.testing.assert_allclose(sim.data.ctrl, at_arrival, atol=1e-9)
        for _ in range(20):
            sim.step()
        before_last_step = torque(cmd, sim.data.qpos[7:].copy(), sim.data.qvel[6:].copy())
        sim.step()
        now = torque(cmd, sim.data.qpos[7:], sim.data.qvel[6:])
        if on_arrival:
            np.testing.assert_allclose(sim.data.ctrl, at_arrival, atol=1e-9)
            assert np.abs(at_arrival - now).max() > 0.1  # the state moved: a recomputed torque would differ
        sim.apply(cmd)  # the same command again: computed afresh
        sim.step()
        if on_arrival:  # from the sensors, which hold the state at the start of the step taken before
            np.testing.assert_allclose(sim.data.ctrl, before_last_step, atol=1e-9)
            assert np.abs(now - before_last_step).max() > 1e-3
        else:
            np.testing.assert_allclose(sim.data.ctrl, now, atol=1e-9)


def g1_scene(tmp_path, joints, motors: bool = True) -> str:
    """menagerie's G1 saved as an MJCF with one actuator per joint in ``joints`` (torque motors, or position
    servos), as a simulator's own G1 scene would be."""
    import os

    import mujoco

    from pchc_rsl.robots.g1.model import load_g1_spec

    spec = load_g1_spec()
    spec.meshdir = os.path.join(spec.modelfiledir, spec.meshdir)
    for actuator in list(spec.actuators):
        spec.delete(actuator)
    for joint in joints:
        actuator = spec.add_actuator()
        actuator.name, actuator.target, actuator.trntype = joint, joint, mujoco.mjtTrn.mjTRN_JOINT
        if not motors:
            actuator.gainprm[0], actuator.biastype, actuator.biasprm[1] = 40.0, mujoco.mjtBias.mjBIAS_AFFINE, -40.0
    path = tmp_path / "g1_scene.xml"
    path.write_text(spec.to_xml())
    return str(path)


def test_unitree_bands_force_is_a_spring_from_3_m_lowered_a_press_at_a_time():
    """unitree_mujoco's band, worked by hand: 200 N/m and 100 N s/m from (0, 0, 3) m; 12 presses of key 8, 0.2 s
    apart, the last 0.2 s before the release, make it 1.2 m long."""
    from pchc_rsl.deploy.elastic_band import UnitreeBand, band_force

    np.testing.assert_allclose(band_force([0, 0, 0.8], [0, 0, 0], 1.2), [0, 0, 200.0])  # 200 x (2.2 - 1.2)
    np.testing.assert_allclose(band_force([0, 0, 0.8], [0, 0, 0.1], 1.2), [0, 0, 190.0])  # - 100 x 0.1 m/s
    # 1.6 m below and 1.2 m beside the anchor: 2 m away, 200 x (2 - 1.2) = 160 N along (-0.6, 0, 0.8)
    np.testing.assert_allclose(band_force([1.2, 0, 1.4], [0, 0, 0], 1.2), [-96.0, 0, 128.0])
    band = UnitreeBand(12, release_s=6.0)
    assert [band.length(t) for t in (0.0, 3.59, 3.6, 4.5, 5.8, 5.99)] == pytest.approx([0, 0, 0.1, 0.5, 1.2, 1.2])
    assert band.on(5.99) and not band.on(6.0)


@needs_g1
@pytest.mark.parametrize("stays", [True, False], ids=["force-stays", "clean-release"])
def test_unitree_bands_last_force_stays_after_the_release_only_when_told(stays):
    """In unitree_mujoco's loop without its viewer the band's last force stays on the torso after key 9; the clean
    mode takes it away. The force left is the band's at the last step before the release, computed here by hand
    from the torso's position and velocity then."""
    from pchc_rsl.deploy.simulator import G1Simulator

    sim = G1Simulator(hold_up_s=0.3, unitree_band=12, band_force_stays=stays)
    while sim.time < 0.3 - 1e-9:
        position, velocity = sim.data.qpos[:3].copy(), sim.data.qvel[:3].copy()
        sim.step()
    delta = np.array([0.0, 0.0, 3.0]) - position
    direction = delta / np.linalg.norm(delta)
    last = (200.0 * (np.linalg.norm(delta) - 1.2) - 100.0 * velocity @ direction) * direction
    assert 150 < last[2] < 300  # the band still carries most of the robot
    for _ in range(100):
        sim.step()
    left = sim.data.xfrc_applied[sim.torso]
    if stays:
        np.testing.assert_allclose(left[:3], last, atol=1e-9)
        assert sim.band_force_left == pytest.approx(np.round(last, 2).tolist())
    else:
        assert not left.any() and sim.band_force_left == [0.0, 0.0, 0.0]


BAND_SETTLED_S = 1.38
"""s after unitree_mujoco's band (12 presses) lets go of menagerie's G1 in HOLD until both its gyro and its tilt rate
have stayed below 0.05 rad/s for 1 s: they read up to 0.19 rad/s in the first 0.5 s and stay below from 0.38 s on
(measured on the simulator's own state, without the deploy's check, in docs/deploy.md)."""


@needs_g1
def test_the_policy_waits_until_the_robot_stands_still_after_unitrees_band_lets_go(tmp_path):
    """The automatic sequence asks for the policy 0.12 s after the band lets go (HOLD from 2.52 s, --hold-seconds
    3.6, release at 6 s), while the robot sways: it starts only once the sway has settled, at 6 s + BAND_SETTLED_S."""
    report = deploy_report(tmp_path / "band.json", WALK_ONNX, "--mujoco", "--unitree-band", "12", "--hold-up", "6",
                           "--hold-seconds", "3.6", "--seconds", "0.1", timeout=600)
    hold_at, policy_at = report["events"][2][0], report["events"][3][0]
    assert hold_at + 3.6 < 6.2  # asked for while the robot still swung
    assert policy_at >= 6.0 + BAND_SETTLED_S - 0.05
    assert report["stand_still"]["waited_s"] == pytest.approx(policy_at - (hold_at + 3.6), abs=0.021)
    assert not report["fell"]


@needs_g1
def test_a_scene_in_the_sdk_motor_order_is_simulated_and_any_other_refused(tmp_path):
    """--scene takes a G1 whose 29 torque motors follow unitree_sdk2's order (unitree_mujoco's scene_29dof.xml is
    one); the simulator then drives that model. Swapped motors or position servos are refused in one line."""
    from pchc_rsl.deploy.simulator import G1Simulator

    sim = G1Simulator(scene=g1_scene(tmp_path, MOTOR_JOINTS), timestep=0.004)
    assert sim.model.nu == NUM_MOTORS and sim.model.opt.timestep == 0.004
    cmd = MotorCommand(q=MOTOR_DEFAULT_POS + 0.1, kp=np.full(NUM_MOTORS, 30.0), kd=np.zeros(NUM_MOTORS))
    sim.apply(cmd)
    sim.step()
    np.testing.assert_allclose(sim.data.actuator_force, np.full(NUM_MOTORS, 3.0), atol=1e-9)  # 30 x 0.1 rad
    swapped = [MOTOR_JOINTS[1], MOTOR_JOINTS[0], *MOTOR_JOINTS[2:]]
    with pytest.raises(ValueError, match="not a 29-DoF G1 in unitree_sdk2's motor order"):
        G1Simulator(scene=g1_scene(tmp_path, swapped))
    with pytest.raises(ValueError, match="not torque motors"):
        G1Simulator(scene=g1_scene(tmp_path, MOTOR_JOINTS, motors=False))


def test_a_stale_lowstate_damps_within_100_ms():
    robot = FakeRobot(silent_after=5.0)  # the policy runs from 3.5 s
    run = fake_deployment(robot)
    run.run(seconds=10)
    damped = [t for t, cmd in robot.sent if is_damping(cmd)]
    assert run.safety.reason.startswith("stale LowState")
    assert damped and 5.0 < damped[0] <= 5.1
    assert not any(is_damping(cmd) for t, cmd in robot.sent if t <= 5.0)


def test_ctrl_c_damps_then_exits():
    robot = FakeRobot(interrupt_at=4.0)
    run = fake_deployment(robot)
    run.run(seconds=10)  # returns: the KeyboardInterrupt is the operator's stop
    assert run.safety.mode is Mode.DAMPING and run.safety.reason == "Ctrl-C"
    after = [cmd for t, cmd in robot.sent if t >= 4.0]
    assert after and all(is_damping(cmd) for cmd in after)
    assert robot.sent[-1][0] >= 4.0 + 0.5 - 0.02  # half a second of damping before the exit


def swaying_until(t_still: float, rate: float = 0.1):
    """An IMU that reads a pitch rate of ``rate`` rad/s until ``t_still`` and nothing after."""
    return lambda t: np.array([0.0, rate if t < t_still - 1e-9 else 0.0, 0.0])


@pytest.mark.parametrize("asked_by", ["auto", "key"])
def test_the_policy_starts_once_the_robot_stands_still(asked_by):
    """A robot that sways at 0.1 rad/s until 4.0 s: HOLD begins at 2.5 s (the ramp from 0.5 s), the policy is asked
    for at 3.5 s (the automatic sequence's 1 s of hold, or the key p, pressed twice), said to wait once, and starts
    at 5.0 s, when the gyro has read 0 for 1 s; asked for again while it waits, nothing changes."""
    lines = []
    robot = FakeRobot(gyro=swaying_until(4.0))
    run = fake_deployment(robot, log=lines.append)
    if asked_by == "key":
        run.auto = None
        presses = {0.5: "s", 3.5: "p", 4.2: "p"}
        run.inputs = [type("Keys", (), {"pending": lambda _: [presses.pop(k) for k in list(presses)
                                                             if abs(k - robot.t) < 1e-9]})()]
    while robot.t < 5.2:
        run.tick()
        robot.wait_tick()
    assert [(t, mode) for t, mode, _ in run.record.events[:4]] == [(0.0, "ZERO_TORQUE"), (0.5, "RAMP"), (2.5, "HOLD"),
                                                                   (5.0, "POLICY")]
    waiting = [line for line in lines if line.startswith("waiting for the robot to stand still")]
    assert waiting == ["waiting for the robot to stand still: gyro 0.100 rad/s (bound 0.05), tilt rate 0.000/s "
                       "(bound 0.05), for 1 s"]
    assert "the robot stands still after 1.5 s: gyro 0.000 rad/s" in "\n".join(lines)
    assert run.waited_s == pytest.approx(1.5)


def test_the_stand_still_check_can_be_skipped_and_a_still_robot_does_not_wait():
    """Without the check the swaying robot's policy starts when asked (3.5 s); a robot still from the start starts
    it there too, without a word about waiting."""
    from pchc_rsl.deploy.deployment import AutoSequence, Deployment
    from pchc_rsl.deploy.policy_step import PolicyStep

    for robot, wait_still in ((FakeRobot(gyro=swaying_until(4.0)), False), (FakeRobot(), True)):
        lines = []
        run = Deployment(PolicyStep(WALK_ONNX), robot, [0.5, 0.5], (0.5, 0.0, 0.0), AutoSequence(),
                         log=lines.append, wait_still=wait_still)
        run.safety.collapse_s = np.inf
        run.run(seconds=0.1)
        assert run.record.events[3][:2] == (3.5, "POLICY")
        assert not any("stand still" in line for line in lines)


def test_the_remote_starts_the_robot_and_moves_lambda_and_the_command_once_per_press():
    robot = FakeRobot()
    run = fake_deployment(robot)
    run.auto = None
    run.tick()
    robot.remote = Remote(frozenset({"start"}))
    run.tick()
    assert run.safety.mode is Mode.RAMP
    robot.remote = Remote(frozenset({"R1", "up"}))
    for _ in range(5):  # held for five ticks: one step each
        robot.wait_tick()
        run.tick()
    assert run.preference.value.tolist() == pytest.approx([0.4, 0.6]) and run.command.value[0] == pytest.approx(0.6)
    robot.remote = Remote()
    robot.wait_tick()
    run.tick()
    robot.remote = Remote(frozenset({"L1"}))
    robot.wait_tick()
    run.tick()
    assert run.preference.value.tolist() == pytest.approx([0.5, 0.5])
    robot.remote = Remote(frozenset({"select"}))
    robot.wait_tick()
    run.tick()
    assert run.safety.mode is Mode.DAMPING and run.safety.reason == "operator"


class Keys:
    """An input source that yields the given keys, one per tick."""

    def __init__(self, keys) -> None:
        self.keys = list(keys)

    def pending(self) -> list:
        return [self.keys.pop(0)] if self.keys else []


def velocity_command_in_observation(run) -> np.ndarray:
    """The newest frame's velocity_command entries, as the network saw them."""
    start = 0
    for name, size in run.policy.frame_layout:
        if name == "velocity_command":
            return run.policy.history[0, start:start + size].astype(float)
        start += size
    raise AssertionError("no velocity_command in the frame")


def policy_running(robot, policy_file: str, log=lambda *_: None):
    run = fake_deployment(robot, policy_file, log)
    run.auto = None
    run.tick()  # the first state: zero torque
    run.safety.request(Mode.RAMP, robot.t, robot.read())
    for _ in range(int(RAMP_S / 0.02) + 5):
        robot.wait_tick()
        run.tick()
        if run.safety.request(Mode.POLICY, robot.t, robot.read()):
            return run
    raise AssertionError(f"the policy did not start: {run.safety.mode} ({run.safety.reason})")


def test_keys_steer_forward_lateral_and_yaw_into_the_observation(steering_onnx):
    robot = FakeRobot()
    run = policy_running(robot, steering_onnx)
    run.inputs = [Keys("wwaaaqeeez" + "x" * 20 + "d" * 9 + "e" * 14)]
    expected = [(0.5, 0, 0)]
    steps = {"w": (0, 0.1), "x": (0, -0.1), "a": (1, 0.1), "d": (1, -0.1), "q": (2, 0.1), "e": (2, -0.1)}
    for key in "wwaaaqeeez" + "x" * 20 + "d" * 9 + "e" * 14:
        value = list(expected[-1])
        if key == "z":
            value = [0.0, 0.0, 0.0]
        else:
            k, delta = steps[key]
            value[k] = min(max(value[k] + delta, STEERING_RANGES[list(STEERING_RANGES)[k]][0]),
                           STEERING_RANGES[list(STEERING_RANGES)[k]][1])
        expected.append(tuple(value))
        robot.wait_tick()
        run.tick()
        np.testing.assert_allclose(run.command.value, value, atol=1e-9)
        np.testing.assert_allclose(velocity_command_in_observation(run), value, atol=1e-6)
    assert run.command.value.tolist() == pytest.approx([-0.5, -0.5, -1.0])  # clipped at each range's bottom


def test_the_remote_sticks_steer_as_deploy_real_maps_them(steering_onnx):
    """cmd = (ly, -lx, -rx) scaled to each range (full forward: the top, full back: the bottom), a dead band of 0.1
    with the rest rescaled; letting go of the sticks stops the robot."""
    robot = FakeRobot()
    run = policy_running(robot, steering_onnx)
    for (lx, ly, rx), expected in [((0.0, 1.0, 0.0), (1.0, 0.0, 0.0)),
                                   ((0.0, -1.0, 0.0), (-0.5, 0.0, 0.0)),
                                   ((-0.55, 0.55, 1.0), (0.5 * 1.0, 0.5 * 0.5, -1.0)),
                                   ((0.05, 0.08, -0.09), (0.0, 0.0, 0.0))]:  # inside the dead band: released
        robot.remote = Remote(lx=lx, ly=ly, rx=rx)
        robot.wait_tick()
        run.tick()
        np.testing.assert_allclose(run.command.value, expected, atol=1e-6)
        np.testing.assert_allclose(velocity_command_in_observation(run), expected, atol=1e-6)


def test_steering_a_policy_without_that_command_is_refused_once(forward_only_onnx, tmp_path):
    """A walker trained on forward speed only: one line per refused component however often it is asked for, and
    its command stays at 0 there. A file without ranges (exported before they were recorded) gets a note on the
    fallback (forward speed only)."""
    from pchc_rsl.deploy.policy_step import PolicyStep

    assert "no command ranges" in PolicyStep(walker_with_ranges(tmp_path, None)).command_note
    assert not PolicyStep(WALK_ONNX).command_note  # the shipped walker records its ranges
    lines = []
    robot = FakeRobot()
    run = policy_running(robot, forward_only_onnx, log=lines.append)
    run.inputs = [Keys("aaaaddqqe")]
    robot.remote = Remote(lx=1.0, rx=-1.0)
    for _ in range(12):
        robot.wait_tick()
        run.tick()
    refusals = [line for line in lines if "takes no" in line]
    assert sorted(refusals) == sorted([
        "this policy takes no lateral command (trained with lin_vel_y 0..0); a / d and the left stick sideways do "
        "nothing",
        "this policy takes no yaw rate command (trained with ang_vel_z 0..0); q / e and the right stick sideways do "
        "nothing"])
    assert run.command.value[1:].tolist() == [0.0, 0.0]


def test_the_fixed_rate_loop_keeps_its_grid():
    from pchc_rsl.deploy.fixed_rate import FixedRateLoop

    clock = {"t": 0.0}
    sleeps = []

    def sleep(s):
        sleeps.append(s)
        clock["t"] += s

    loop = FixedRateLoop(0.02, clock=lambda: clock["t"], sleep=sleep)
    for work in [0.005, 0.015, 0.005, 0.03, 0.005]:
        clock["t"] += work  # the tick's work
        loop.wait()
    # tick k is due at k * 20 ms from the first call (at 5 ms): a sleep-after-the-work loop would drift by the work
    assert sleeps[:3] == pytest.approx([0.02, 0.005, 0.015])
    assert loop.overruns == 1 and loop.worst_late_s == pytest.approx(0.01)
    assert loop.summary()["worst_late_at_s"] == pytest.approx(0.09)  # the fourth tick's end, 90 ms after the first


# ---------------------------------------------------------------------------------------------- the policy
@needs_g1
def test_the_deploy_observation_is_the_training_envs():
    """The frame history built from a RobotState equals the env's policy observation, step after step, and the
    ONNX action equals the torch policy's."""
    import torch

    from pchc_rsl.deploy.policy_step import PolicyStep
    from pchc_rsl.evaluation.checkpoint import evaluation_config, loaded_policy, task_config_of

    config = task_config_of("policies/g1_walk.pt", "g1-walk", "test", "walking")
    runner, torch_policy = loaded_policy("policies/g1_walk.pt", evaluation_config(config, "mild", 1, 0))
    env = runner.env
    env.preferences.hold(torch.tensor([0.25, 0.75]))
    env.commands[:] = torch.tensor([0.5, 0.0, 0.0])
    obs = env.get_observations()
    step = PolicyStep(WALK_ONNX)

    def robot_state() -> RobotState:
        r = env.robot
        return RobotState(q=step.joints.to_motors(r.joint_pos[0].numpy(), MOTOR_DEFAULT_POS),
                          dq=step.joints.to_motors(r.joint_vel[0].numpy(), np.zeros(NUM_MOTORS)),
                          tau=np.zeros(NUM_MOTORS), quat=r.base_quat[0].double().numpy(),
                          gyro=r.base_ang_vel[0].double().numpy())

    step.reset(robot_state(), env.commands[0].numpy())
    for _ in range(30):
        with torch.no_grad():
            action = torch_policy(obs)[0].numpy()
        step(robot_state(), np.array([0.25, 0.75]), env.commands[0].numpy())
        np.testing.assert_allclose(step.history.reshape(-1), obs["policy"][0].numpy(), atol=1e-5)
        np.testing.assert_allclose(step.last_action, np.clip(action, -10, 10), atol=1e-4)
        obs, *_ = env.step(torch.as_tensor(action).unsqueeze(0))


def run_cli(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pchc_rsl.cli.deploy", *args], capture_output=True, text=True,
                          timeout=timeout)


def deploy_report(report_file, *args: str, timeout: float = 60) -> dict:
    """pchc-deploy's report of a run that went through the whole sequence and ended by itself."""
    done = run_cli(*args, "--report", str(report_file), timeout=timeout)
    assert done.returncode == 0, done.stderr
    report = json.loads(report_file.read_text())
    assert [e[1] for e in report["events"]] == ["ZERO_TORQUE", "RAMP", "HOLD", "POLICY"]
    assert report["final_mode"] == "DAMPING" and report["reason"] == "end of run"
    return report


@needs_g1
def test_the_shipped_walker_walks_in_process(tmp_path):
    """The 20-joint walker on the 29-DoF robot (waist and wrists held by PD), commanded 0.5 m/s at (1, 0)."""
    report = deploy_report(tmp_path / "deploy.json", WALK_ONNX, "--mujoco", "--preference", "1,0", "--seconds", "5",
                           timeout=600)
    assert not report["fell"]
    assert report["base_distance"] > 1.0  # it walks (about 0.4 m/s), it does not only stand


# ---------------------------------------------------------------------------------------------- over DDS
LOWCMD_LISTENER = """
import json, sys, time
from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowCmd_
from pchc_rsl.deploy.sdk import RawReader, start_dds
from pchc_rsl.deploy.wire_format import crc32, lowcmd_from_cdr
domain, out = int(sys.argv[1]), sys.argv[2]
seen = []
def on_sample(sample, at):
    packed = lowcmd_from_cdr(sample)
    seen.append((at, crc32(packed) == int(packed["crc"][0]), float(packed["motor_cmd"][0]["kp"][3])))
start_dds(domain, "lo")
reader = RawReader(domain, "rt/lowcmd", LowCmd_, on_sample, depth=256)
print("listening", flush=True)
sys.stdin.read()  # until the test closes it
json.dump(seen, open(out, "w"))
"""


LOWCMD_WRITER = """
import sys, time
import numpy as np
from pchc_rsl.deploy.robot_io import MotorCommand
from pchc_rsl.deploy.sdk import DdsRobot
robot = DdsRobot(int(sys.argv[1]), "lo")
cmd = MotorCommand(q=np.linspace(-0.5, 0.5, 29), kp=np.full(29, 77.0), kd=np.full(29, 2.0))
end = time.monotonic() + float(sys.argv[2])
while time.monotonic() < end:  # a 50 Hz control loop that sets the command
    robot.send(cmd)
    time.sleep(0.02)
robot.close()
print(robot.sent, robot.stream.loop.overruns)
"""


def lowcmd_per_second(seen: list, kp: float) -> np.ndarray:
    """Messages with motor 3's kp equal to ``kp`` (one phase of a run), counted in each whole second."""
    times = np.array([at for at, _, motor_kp in seen if abs(motor_kp - kp) < 1e-3])
    whole = int(times[-1] - times[0])
    return np.histogram(times, bins=whole, range=(times[0], times[0] + whole))[0]


@needs_sdk
def test_the_deploys_dds_end_writes_lowcmd_at_500_hz(tmp_path):
    """The deploy's DDS end in one process, a subscriber on loopback in another: >= 450 LowCmd in each whole second
    while the 50 Hz loop sets commands, every CRC valid (checked with the subscriber's own decoding)."""
    domain = str(random.randint(100, 232))
    listener = subprocess.Popen([sys.executable, "-c", LOWCMD_LISTENER, domain, str(tmp_path / "seen.json")],
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert listener.stdout.readline().strip() == "listening"
        done = subprocess.run([sys.executable, "-c", LOWCMD_WRITER, domain, "4"], capture_output=True, text=True,
                              timeout=120)
        assert done.returncode == 0, done.stderr
    finally:
        listener.communicate("", timeout=30)
    seen = json.loads((tmp_path / "seen.json").read_text())
    assert seen and all(ok for _, ok, _ in seen)
    counts = lowcmd_per_second(seen, 77.0)
    assert len(counts) >= 3 and counts.min() >= 450, counts


@pytest.mark.slow
@needs_sdk
@needs_g1
def test_lowcmd_streams_at_the_robots_rate_during_the_policy(tmp_path):
    """A subscriber on loopback, in its own process, sees the policy's LowCmd (told apart by the policy's knee gain,
    which the ramp and the hold do not use) at >= 450 a second in every whole second, each CRC valid; and the walker
    does not fall over DDS."""
    from pchc_rsl.deploy.policy_step import PolicyStep

    knee_kp = PolicyStep(WALK_ONNX).kp[WALK_JOINTS.index("left_knee_joint")]
    domain = str(random.randint(100, 232))
    listener = subprocess.Popen([sys.executable, "-c", LOWCMD_LISTENER, domain, str(tmp_path / "seen.json")],
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert listener.stdout.readline().strip() == "listening"
        report = deploy_report(tmp_path / "deploy.json", WALK_ONNX, "--sim", "--domain", domain, "--preference",
                               "1,0", "--seconds", "3", timeout=300)
    finally:
        listener.communicate("", timeout=30)
    seen = json.loads((tmp_path / "seen.json").read_text())
    assert seen and all(ok for _, ok, _ in seen)
    counts = lowcmd_per_second(seen, knee_kp)
    assert len(counts) >= 2 and counts.min() >= 450, counts
    assert not report["fell"] and report["bridge"]["commands_bad_crc"] == 0
    assert report["lowcmd"]["rate_hz"] == 500


@pytest.mark.slow
@needs_g1
@pytest.mark.parametrize("mode", [(), ("--pd-on-arrival",)], ids=["pd-every-step", "pd-on-arrival"])
def test_hold_stands_10_s_after_the_gantry_lets_go(tmp_path, mode):
    """The gantry (hold-up band) lets go at 3 s; HOLD lasts until 15.5 s: the pelvis stays above 0.7 m (standing is
    0.75 m; the policy's own gains let it sink to 0.1 m) and no watchdog trips. Both PD semantics at 500 Hz physics."""
    report = deploy_report(tmp_path / "hold.json", WALK_ONNX, "--mujoco", *mode, "--hold-up", "3",
                           "--hold-seconds", "13", "--seconds", "0.1", timeout=600)
    assert report["min_height_after_release"] > 0.7
    assert report["events"][3][0] >= 15.4  # the policy started only after 12.4 s of standing alone


@pytest.mark.slow
@needs_g1
@pytest.mark.parametrize("preference", ["1,0", "0.75,0.25", "0.5,0.5", "0.25,0.75", "0,1"])
def test_the_shipped_walker_walks_10_s_with_pd_on_arrival(tmp_path, preference):
    """unitree_mujoco's semantics (the torque held from each LowCmd's arrival, from sensors one physics step old)
    with LowCmd at 500 Hz and 500 Hz physics: no fall, and it walks (0.5 m/s commanded). At their default 200 Hz the
    sensors are 5 ms old and the standing gains make the free feet chatter on the gantry (docs/deploy.md)."""
    report = deploy_report(tmp_path / "walk.json", WALK_ONNX, "--mujoco", "--pd-on-arrival", "--timestep", "0.002",
                           "--preference", preference, "--seconds", "10", timeout=600)
    assert not report["fell"] and report["policy_seconds"] >= 10
    assert report["base_distance"] > 2.5


# ---------------------------------------------------------------------------------------------- command sequence
def test_commands_integrate_as_exact_arcs():
    """0.5 m/s turning at 0.5 rad/s is a circle of radius 1 m about (0, 1): a quarter after pi s at (1, 1) facing
    +y, half after 2 pi s at (0, 2) facing -x; straight and sideways pieces add R(heading) v t."""
    from pchc_rsl.deploy.end_point import in_start_frame, integrate_twist

    assert integrate_twist([(math.pi, (0.5, 0.0, 0.5))]) == pytest.approx((1.0, 1.0, math.pi / 2))
    assert integrate_twist([(2 * math.pi, (0.5, 0.0, 0.5))]) == pytest.approx((0.0, 2.0, math.pi))
    assert integrate_twist([(math.pi, (0.5, 0.0, -0.5))]) == pytest.approx((1.0, -1.0, -math.pi / 2))
    # a side step to the left while facing +y goes towards -x; then 2 s forward facing +y
    assert integrate_twist([(3.0, (0.0, 0.3, 0.0)), (2.0, (0.5, 0.0, 0.0))], start=(1.0, 1.0, math.pi / 2)) == \
        pytest.approx((0.1, 2.0, math.pi / 2))
    assert integrate_twist([(4.0, (0.0, 0.0, 0.0))]) == (0.0, 0.0, 0.0)
    # seen from (1, 2) facing +y, the point (1, 3) facing -x is 1 m ahead, turned a quarter left
    assert in_start_frame((1.0, 2.0, math.pi / 2), (1.0, 3.0, math.pi)) == pytest.approx((1.0, 0.0, math.pi / 2))


def sequence_file(folder, text: str, name: str = "seq.txt") -> str:
    path = folder / name
    path.write_text(text)
    return str(path)


def test_a_command_sequence_holds_each_row_until_the_next():
    from pchc_rsl.deploy.command_sequence import read_command_sequence

    sequence = read_command_sequence("examples/steering_sequence.txt", STEERING_RANGES)
    # the file is tools/diagnostics/steering_sequence.py's sequence
    steering = load_tool("diagnostics/steering_sequence")
    starts = np.cumsum([0.0] + [seconds for _, seconds, _ in steering.SEQUENCE[:-1]])
    assert [(row.start, row.command) for row in sequence.rows] == list(zip(starts, [c for *_, c in steering.SEQUENCE]))
    assert [sequence.at(t).command for t in (0.0, 2.98, 3.0, 8.99, 11.5, 12.0, 100.0)] == [
        (0.5, 0, 0), (0.5, 0, 0), (0.3, 0, 0.5), (0.3, 0, -0.5), (0, 0.3, 0), (0, 0, 0), (0, 0, 0)]


def test_each_bad_command_sequence_is_refused_naming_its_row(tmp_path):
    from pchc_rsl.deploy.command_sequence import read_command_sequence

    cases = {
        "0 0.5 0 0\n2 0.5 0\n": ":2: a row is four numbers (seconds forward lateral yaw_rate), got '2 0.5 0'",
        "0 0.5 0 0\n2 fast 0 0\n": ":2: a row is four numbers",
        "0 0.5 0 nan\n": ":1: a row is four numbers",
        "# header\n0 0.5 0 0\n3 0.3 0 0.5\n\n3 0 0 0\n": ":5: rows go forward in time; 3 s does not come after the "
                                                        "row at 3 s (line 3)",
        "0 0.5 0 0\n3 0.3 0 0.5\n2 0 0 0\n": ":3: rows go forward in time",
        "1 0.5 0 0\n": ":1: the first row starts when the policy does, at 0 s; got 1 s",
        "0 0.5 0 0\n4 1.5 0 0\n": ":2: forward 1.5 m/s is outside the range the policy was trained in, -0.5..1 m/s",
        "0 0 0 -1.2\n": ":1: yaw rate -1.2 rad/s is outside the range the policy was trained in, -1..1 rad/s",
        "# only a comment\n\n": ": no command rows; write one per line: seconds forward lateral yaw_rate",
        "": ": no command rows",
    }
    for i, (text, expected) in enumerate(cases.items()):
        path = sequence_file(tmp_path, text, f"seq{i}.txt")
        with pytest.raises(ValueError) as refused:
            read_command_sequence(path, STEERING_RANGES)
        assert str(refused.value) == path + expected or str(refused.value).startswith(path + expected), refused.value
    forward_only = {k: tuple(v) for k, v in FORWARD_ONLY.items()}
    path = sequence_file(tmp_path, "0 0.5 0 0\n1 0.5 0.2 0\n")
    with pytest.raises(ValueError, match=":2: lateral 0.2 m/s, but this policy takes no lateral command"):
        read_command_sequence(path, forward_only)
    with pytest.raises(ValueError, match="this policy takes no velocity command"):
        read_command_sequence(path, None)
    with pytest.raises(ValueError, match="--command-sequence .*missing.txt: No such file"):
        read_command_sequence(str(tmp_path / "missing.txt"), STEERING_RANGES)


def test_a_bad_command_sequence_stops_the_deploy_before_the_policy_loads(monkeypatch, tmp_path):
    """Refused in one line from the file and the policy's metadata: the network (and torch, DDS) never load."""
    from pchc_rsl.cli import deploy
    from pchc_rsl.deploy import policy_step

    def no_loading(*_):
        raise AssertionError("the policy was loaded before the command sequence was checked")

    monkeypatch.setattr(policy_step.PolicyStep, "__init__", no_loading)
    path = sequence_file(tmp_path, "0 0.5 0 0\n2 0.5 0 3\n")
    for where in (["--mujoco"], ["--network", "lo"]):
        with pytest.raises(SystemExit) as exit_:
            deploy.main([WALK_ONNX, *where, "--command-sequence", path])
        assert str(exit_.value.code) == (f"pchc-deploy: {path}:2: yaw rate 3 rad/s is outside the range the policy "
                                         "was trained in, -1..1 rad/s")
    late = sequence_file(tmp_path, "0 0.5 0 0\n12 0 0 0\n", "late.txt")
    with pytest.raises(SystemExit) as exit_:
        deploy.main([WALK_ONNX, "--mujoco", "--command-sequence", late])
    assert f"{late}:2: the row at 12 s starts after the run's 10 s of policy; give --seconds" in str(exit_.value.code)


@needs_g1
def test_a_command_sequence_steers_the_deploy_and_the_report_gives_the_end_point(tmp_path):
    """In process, 1 s forward at 0.5 m/s then 1 s turning left (0.3 m/s, 0.5 rad/s): the commands change at the
    rows' times, and the report's end point compares the pelvis with the commanded one, worked by hand: 0.5 m, then
    an arc of radius 0.6 m turning 0.5 rad/s for the rest of the policy's time (2 s and the tick that reached it)."""
    path = sequence_file(tmp_path, "# a short walk\n0 0.5 0 0\n1 0.3 0 0.5\n")
    report = deploy_report(tmp_path / "walk.json", WALK_ONNX, "--mujoco", "--preference", "1,0", "--seconds", "2",
                           "--command-sequence", path, timeout=600)
    assert report["policy_commands"] == [[0.0, 0.5, 0.0, 0.0], [1.0, 0.3, 0.0, 0.5]]
    end = report["end_point"]
    turned = 0.5 * (report["policy_seconds"] - 1.0)
    assert 2.0 <= report["policy_seconds"] <= 2.021
    commanded = (0.5 + 0.6 * math.sin(turned), 0.6 * (1 - math.cos(turned)), math.degrees(turned))
    assert end["commanded"][:2] == pytest.approx(commanded[:2], abs=1e-3)  # as reported: m to 3 decimals
    assert end["commanded"][2] == pytest.approx(commanded[2], abs=0.06)  # degrees to 1
    reached = end["reached"]
    assert 0.2 < reached[0] < 1.2  # it walked forward
    assert reached[2] == pytest.approx(end["imu_heading_deg"], abs=0.2)  # the trace and the IMU agree
    assert end["off_m"] == pytest.approx(math.hypot(reached[0] - commanded[0], reached[1] - commanded[1]), abs=2e-3)


# ---------------------------------------------------------------------------------------------- bad input
def test_bad_input_is_one_line(tmp_path, forward_only_onnx):
    toy = tmp_path / "toy.onnx"
    from pchc_rsl.cli import export_onnx, train

    train.main(["--task", "toy", "--num-envs", "2", "--max-iterations", "1", "--log-dir", str(tmp_path / "toy")])
    export_onnx.main([str(tmp_path / "toy" / "model_0.pt"), "-o", str(toy)])
    cases = {
        (str(toy), "--mujoco"): "deploy metadata",
        (WALK_ONNX, "--mujoco", "--preference", "0.7,0.7"): "sum to 1",
        (WALK_ONNX, "--network", "no-such-if0"): "names no network interface",
        (str(tmp_path / "missing.onnx"), "--mujoco"): "no policy file",
        ("policies/g1_walk.pt", "--mujoco"): "pchc-deploy: policies/g1_walk.pt is a PyTorch checkpoint",
        (WALK_ONNX, "--mujoco", "--lowcmd-hz", "20"): "--lowcmd-hz 20 is outside [50, 1000]",
        (WALK_ONNX, "--network", "lo", "--scene", "g1.xml"): "--scene is the simulated robot's model",
        (WALK_ONNX, "--mujoco", "--scene", str(tmp_path / "missing.xml")): "no scene file at",
        (WALK_ONNX, "--mujoco", "--lowcmd-hz", "2000"): "--lowcmd-hz 2000 is outside [50, 1000]",
        (forward_only_onnx, "--mujoco", "--command", "0.5,0.3,0"):
            "--command's lateral 0.3 m/s: this policy takes no lateral",
        (WALK_ONNX, "--mujoco", "--command", "1.5"): "forward 1.5 m/s is outside the range the policy was trained in",
        (WALK_ONNX, "--mujoco", "--band-force-stays"): "give --unitree-band PRESSES too",
        (WALK_ONNX, "--network", "lo", "--unitree-band", "12"): "--unitree-band is the simulated robot's gantry",
        (WALK_ONNX, "--mujoco", "--unitree-band", "-1"): "must be a whole number of key presses >= 0",
    }
    if not sdk_available():
        cases.pop((WALK_ONNX, "--network", "no-such-if0"))
    for args, expected in cases.items():
        done = run_cli(*args)
        assert done.returncode != 0
        lines = [line for line in done.stderr.strip().splitlines() if line]
        assert len(lines) == 1 and expected in lines[0], (args, done.stderr)
        assert "'" not in lines[0].split(":", 1)[1][:3], lines[0]  # the message itself, not its repr


def test_arguments_are_checked_before_the_policy_loads(monkeypatch, capsys):
    """A bad preference is refused from the file's metadata alone: the network (and torch) never load."""
    from pchc_rsl.cli import deploy
    from pchc_rsl.deploy import policy_step

    def no_loading(*_):
        raise AssertionError("the policy was loaded before the arguments were checked")

    monkeypatch.setattr(policy_step.PolicyStep, "__init__", no_loading)
    with pytest.raises(SystemExit) as exit_:
        deploy.main([WALK_ONNX, "--mujoco", "--preference", "0.2,0.2,0.6"])
    assert "the policy weighs 2 objectives (disturbance, stride)" in str(exit_.value.code)


def test_a_sim_run_that_fell_behind_real_time_is_no_pass(monkeypatch, capsys, tmp_path):
    """--sim prints its summary, writes the report, then exits non-zero naming the cause and the remedy."""
    from pchc_rsl.cli import deploy

    bridge = {"sim_time": 5.2, "wall_s": 9.0, "real_time_factor": 0.578, "late_share": 0.82, "slowest_step_ms": 41.0,
              "timestep": 0.002, "kept_real_time": False, "commands_received": 4500, "commands_bad_crc": 0}
    report = {"task": "g1-walk", "final_mode": "DAMPING", "reason": "end of run", "policy_seconds": 5.0,
              "messages_sent": 4600, "messages_received": 2592, "events": [], "fell": False, "base_distance": 0.84,
              "lowstate": {"received": 2592, "fresh": 2592, "seconds": 9.0}, "bridge": bridge}
    monkeypatch.setattr(deploy, "deploy", lambda *_: report)
    with pytest.raises(SystemExit) as exit_:
        deploy.main([WALK_ONNX, "--sim", "--seconds", "5", "--report", str(tmp_path / "r.json")])
    message = str(exit_.value.code)
    assert "fell behind real time: 5.2 s simulated in 9.0 s (real-time factor 0.58, bound 0.9)" in message
    assert "82% of physics steps late" in message and "--timestep 0.004" in message and "--mujoco" in message
    out = capsys.readouterr().out
    assert "5.2 s simulated in 9.0 s" in out and "did not fall, walked 0.84 m" in out
    assert json.loads((tmp_path / "r.json").read_text())["bridge"]["kept_real_time"] is False


@needs_sdk
def test_no_lowstate_names_the_interface_and_domain():
    domain = str(random.randint(100, 232))
    done = run_cli(WALK_ONNX, "--network", "lo", "--domain", domain)
    assert done.returncode != 0
    assert "no rt/lowstate within 3 s on interface lo, DDS domain " + domain in done.stderr


def test_a_missing_sdk_names_the_extra(monkeypatch):
    import builtins

    from pchc_rsl.deploy import sdk

    real_import = builtins.__import__

    def no_sdk(name, *args, **kwargs):
        if name.startswith("unitree_sdk2py"):
            raise ImportError(f"No module named '{name}'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_sdk)
    with pytest.raises(sdk.SdkMissing, match=r'pip install -e "\.\[deploy\]"'):
        sdk.sdk()


@pytest.mark.slow
@needs_sdk
@needs_g1
@pytest.mark.parametrize("preference", ["1,0", "0,1"])
def test_the_shipped_walker_walks_10_s_over_dds_as_in_process(tmp_path, preference):
    """Sim-to-sim: 10 s of policy through the bridge in real time against the same run in lockstep in-process.
    Step by step the two part within a fraction of a second (the DDS path reads a state up to 2 ms old and its
    commands land between physics steps), so the bound is on the gait: the posture (mean joint angles) within
    0.05 rad rms, each joint's swing (std) within 0.03 rad rms, the distance walked within 35%."""
    local, dds = (deploy_report(tmp_path / f"{transport[2:]}.json", WALK_ONNX, transport, "--preference", preference,
                                "--seconds", "10", timeout=120) for transport in ("--mujoco", "--sim"))
    for report in (local, dds):
        assert not report["fell"] and report["policy_seconds"] >= 10
    rms = lambda a, b: float(np.sqrt(np.mean((np.array(a) - np.array(b)) ** 2)))  # noqa: E731
    assert rms(local["policy_joint_mean"], dds["policy_joint_mean"]) < 0.05
    assert rms(local["policy_joint_std"], dds["policy_joint_std"]) < 0.03
    assert abs(dds["base_distance"] - local["base_distance"]) < 0.35 * local["base_distance"]


def test_the_browser_console_steers_a_deploy(steering_onnx):
    """The console's widgets (set as the page sets them) reach the deploy loop: start, lambda, the three command
    sliders over their trained ranges, policy."""
    pytest.importorskip("viser")
    import socket

    from pchc_rsl.deploy.web_console import DeployConsole

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    ranges = {"lin_vel_x": (-0.5, 1.0), "lin_vel_y": (-0.5, 0.5), "ang_vel_z": (-1.0, 1.0)}
    console = DeployConsole(["disturbance", "stride"], [0.5, 0.5], ranges, (0.5, 0.0, 0.0), port=port)
    try:
        robot = FakeRobot()
        run = fake_deployment(robot, steering_onnx)
        run.auto = None  # only the console drives it
        run.inputs = [console]
        run.tick()
        assert run.safety.mode is Mode.ZERO_TORQUE
        console.buttons["s"].value = True  # a click
        run.tick()
        assert run.safety.mode is Mode.RAMP
        console.preference_sliders[0].value = 0.8
        assert [(c.min, c.max) for c in console.command_sliders.values()] == [(-0.5, 1.0), (-0.5, 0.5), (-1.0, 1.0)]
        console.command_sliders["lin_vel_x"].value = 0.3
        console.command_sliders["lin_vel_y"].value = -0.2
        console.command_sliders["ang_vel_z"].value = 0.4
        for _ in range(int(RAMP_S / 0.02) + 2):
            robot.wait_tick()
            run.tick()
        assert run.preference.value.tolist() == pytest.approx([0.2, 0.8])
        assert run.command.value.tolist() == pytest.approx([0.3, -0.2, 0.4])
        console.buttons["p"].value = True  # HOLD began a tick ago: the policy waits 1 s for the robot to stand still
        for _ in range(15):  # the console's status is refreshed 4 times a second
            robot.wait_tick()
            run.tick()
        assert run.safety.mode is Mode.HOLD and "waiting for the robot to stand still" in console.status.content
        for _ in range(40):
            robot.wait_tick()
            run.tick()
        assert run.safety.mode is Mode.POLICY
        for _ in range(15):
            robot.wait_tick()
            run.tick()
        assert "policy" in console.status.content and "stride **0.80**" in console.preference_text.content
    finally:
        console.close()


def lowstate_stream(messages: int, new_every: int, noise: float = 0.0, period: float = 0.002) -> list[RobotState]:
    """LowState as a timer publishes it every ``period`` s, its tick counting up: the physics' latest reading, which
    changes only every ``new_every`` messages (a simulator whose physics runs at 1 / new_every of its timer's
    pace), plus sensor noise of ``noise`` rad on a robot."""
    rng = np.random.default_rng(0)
    stream = []
    for i in range(messages):
        state = standing_state(q=MOTOR_DEFAULT_POS + 1e-3 * (i // new_every), received_at=i * period)
        state.q = state.q + noise * rng.standard_normal(NUM_MOTORS)
        state.tick = 2 * i
        stream.append(state)
    return stream


def test_lowstate_that_repeats_a_reading_is_counted_but_not_as_new():
    """A timer at 500 Hz over physics at 250 Hz: 1251 messages in 2.5 s, 626 new readings (every other one, the
    first included); a robot's noisy sensors make every message new."""
    from pchc_rsl.deploy.fresh_states import FreshStates

    for stream, fresh in ((lowstate_stream(1251, 2), 626), (lowstate_stream(1251, 1, noise=1e-4), 1251)):
        states = FreshStates()
        new = [states.add(state) for state in stream]
        assert states.summary() == {"received": 1251, "fresh": fresh, "seconds": 2.5}
        assert sum(new) == fresh and new[0]


def lowstate_report(stream: list[RobotState]) -> dict:
    """A deploy's report over DDS whose LowState was ``stream``."""
    from pchc_rsl.deploy.fresh_states import FreshStates

    states = FreshStates()
    for state in stream:
        states.add(state)
    lowcmd = {"rate_hz": 500.0, "loop_overruns": 0, "loop_worst_late_ms": 0.0, "realtime_priority": True,
              "loop_ticks": 1250, "loop_period_ms": 2.0}
    return {"reason": "", "final_mode": "DAMPING", "policy_seconds": 1.0, "messages_sent": 1250,
            "messages_received": states.received, "lowstate": states.summary(), "lowcmd": lowcmd}


def test_the_summary_warns_when_new_lowstate_readings_come_slower_than_the_robot_sends_them():
    """The message rate of a simulator whose physics lags its LowState timer looks like a robot's; the rate of new
    readings (626 in 2.5 s) shows it and is named. A robot's is not."""
    from pchc_rsl.cli.deploy import summary_lines

    repeated = "\n".join(summary_lines(lowstate_report(lowstate_stream(1251, 2)), None))
    assert ("LowState: 1251 received (500 per second), 626 new readings (250 per second, below the G1's 500: a "
            "simulator that steps slower or runs behind real time (a LowState timer of its own then repeats states)"
            in repeated)
    robot = "\n".join(summary_lines(lowstate_report(lowstate_stream(1251, 1, noise=1e-4)), None))
    assert "LowState: 1251 received (500 per second), 1251 new readings (500 per second)" in robot


def test_a_sim_run_whose_new_readings_lag_is_no_pass_though_the_bridge_kept_real_time():
    """--sim's verdict takes the new readings the deploy saw against the bridge's physics rate: 250 a second from 500
    Hz physics fails the 0.9 bound even where the bridge's own real-time factor passed; 500 a second passes."""
    from pchc_rsl.deploy.real_time import behind_real_time, judged

    bridge = {"sim_time": 2.5, "wall_s": 2.6, "real_time_factor": 0.962, "late_share": 0.01, "slowest_step_ms": 3.0,
              "timestep": 0.002, "kept_real_time": True, "pd_on_arrival": False}
    lagging = judged(bridge, lowstate_report(lowstate_stream(1251, 2))["lowstate"])
    assert lagging["kept_real_time"] is False and lagging["fresh_states_per_second"] == pytest.approx(250.4)
    assert behind_real_time(lagging).startswith(
        "the deploy saw 250 new LowState readings a second from a simulation of 500 Hz physics (bound 0.9 x 500), "
        "although the simulation kept 0.96 of real time")
    every_step = lowstate_report(lowstate_stream(1251, 1))["lowstate"]
    kept = judged(bridge, every_step)
    assert kept["kept_real_time"] is True and kept["fresh_states_per_second"] == pytest.approx(500.4)
    assert judged(bridge | {"kept_real_time": False}, every_step)["kept_real_time"] is False  # its own factor counts


def test_the_summary_says_how_long_the_policy_waited_for_the_robot_to_stand_still():
    from pchc_rsl.cli.deploy import summary_lines

    base = {"reason": "", "final_mode": "DAMPING", "policy_seconds": 10.0, "messages_sent": 500,
            "messages_received": 500, "lowstate": {"received": 500, "fresh": 500, "seconds": 10.0},
            "events": [[0.0, "ZERO_TORQUE", ""], [0.5, "RAMP", ""], [2.5, "HOLD", ""], [7.96, "POLICY", ""]]}
    bounds = {"gyro_bound": 0.05, "tilt_rate_bound": 0.05, "window_s": 1.0}
    waited = summary_lines(base | {"stand_still": bounds | {"waited_s": 4.46}}, None)
    assert waited[1] == ("  the policy waited 4.5 s in HOLD for the robot to stand still (gyro below 0.05 rad/s and "
                         "tilt rate below 0.05/s for 1 s)")
    assert not any("stand still" in line for line in summary_lines(base | {"stand_still": bounds | {"waited_s": 0.0}},
                                                                     None))
    skipped = summary_lines(base | {"stand_still": None}, None)
    assert skipped[1] == "  the policy started without waiting for the robot to stand still (--skip-stand-still-check)"


def test_the_summary_gives_the_end_point_against_the_commanded_one():
    """In a simulator: both points and how far apart; on a robot (no position in LowState): the commanded point
    and the heading change its IMU measured."""
    from pchc_rsl.cli.deploy import summary_lines
    from pchc_rsl.deploy.end_point import end_point_report

    base = {"reason": "", "final_mode": "DAMPING", "policy_seconds": 10.0, "messages_sent": 500,
            "messages_received": 500, "lowstate": {"received": 500, "fresh": 500, "seconds": 10.0}}
    simulated = end_point_report((5.0, 0.0, 0.0), (2.08, -3.42, math.radians(-138.1)))
    assert simulated["off_m"] == pytest.approx(math.hypot(5.0 - 2.08, 3.42), abs=1e-3)
    text = "\n".join(summary_lines(base | {"end_point": simulated}, None))
    assert ("end point: (+2.08 m, -3.42 m, -138 deg) (forward, left, heading from the policy's start); the commands "
            "lead to (+5.00 m, +0.00 m, +0 deg): 4.50 m apart, heading -138 deg off") in text
    robot = end_point_report((5.0, 0.0, 0.0), None, math.radians(-12.0))
    text = "\n".join(summary_lines(base | {"end_point": robot}, None))
    assert "the commands lead to (+5.00 m, +0.00 m, +0 deg)" in text and "the IMU turned -12 deg" in text
