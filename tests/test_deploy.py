"""pchc-deploy's parts: the CRC a G1 checks, the joint map, the remote's bytes, the observation against the training
env's, the safety state machine and its watchdog, the fixed-rate loop, one DDS run on loopback, and bad input."""

from __future__ import annotations

import json
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
def test_lowstate_round_trips_with_the_remote():
    from pchc_rsl.deploy.sdk import lowstate_message, state_of

    state = standing_state()
    state.quat = np.array([0.9, 0.1, -0.2, 0.3]) / np.linalg.norm([0.9, 0.1, -0.2, 0.3])
    state.gyro = np.array([0.5, -0.25, 1.0])
    state.remote = Remote(frozenset({"A", "L1"}), ly=0.5).encode()
    back = state_of(lowstate_message(state, 5), received_at=1.0)
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
    """A robot whose state stops arriving at ``silent_after`` (s); records what was sent and when."""

    def __init__(self, silent_after: float = 1e9, interrupt_at: float = 1e9) -> None:
        self.t, self.silent_after, self.interrupt_at = 0.0, silent_after, interrupt_at
        self.sent, self.received, self.loop = [], 0, None
        self.last_state: RobotState | None = None
        self.remote = Remote()  # what the operator holds on the G1's remote

    def now(self):
        return self.t

    def read(self):
        if self.t <= self.silent_after:
            self.last_state = standing_state(received_at=self.t)
            self.last_state.remote = self.remote.encode()
        return self.last_state

    def send(self, cmd):
        self.sent.append((self.t, cmd))

    def wait_tick(self):
        self.t = round(self.t + 0.02, 6)
        if self.t >= self.interrupt_at:
            self.interrupt_at = 1e9
            raise KeyboardInterrupt


def fake_deployment(robot):
    from pchc_rsl.deploy.deployment import AutoSequence, Deployment
    from pchc_rsl.deploy.policy_step import PolicyStep

    return Deployment(PolicyStep(WALK_ONNX), robot, [0.5, 0.5], 0.5, AutoSequence(), log=lambda *_: None)


def is_damping(cmd: MotorCommand) -> bool:
    return cmd.kp.max() == 0.0 and np.allclose(cmd.kd, DAMPING_KD)


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
    report = deploy_report(tmp_path / "deploy.json", WALK_ONNX, "--mujoco", "--preference", "1,0", "--seconds", "5")
    assert not report["fell"]
    assert report["base_distance"] > 1.0  # it walks (about 0.4 m/s), it does not only stand


# ---------------------------------------------------------------------------------------------- over DDS
@needs_sdk
@needs_g1
def test_the_shipped_walker_over_dds_on_loopback(tmp_path):
    report = deploy_report(tmp_path / "deploy.json", WALK_ONNX, "--sim", "--preference", "1,0", "--seconds", "2")
    assert not report["fell"]
    bridge = report["bridge"]
    assert bridge["commands_bad_crc"] == 0
    assert bridge["commands_received"] >= 0.95 * report["messages_sent"]  # every LowCmd arrived and passed its CRC
    assert report["messages_received"] > 5 * report["messages_sent"]  # LowState at 500 Hz against LowCmd at 50 Hz


# ---------------------------------------------------------------------------------------------- bad input
def test_bad_input_is_one_line(tmp_path):
    toy = tmp_path / "toy.onnx"
    from pchc_rsl.cli import export_onnx, train

    train.main(["--task", "toy", "--num-envs", "2", "--max-iterations", "1", "--log-dir", str(tmp_path / "toy")])
    export_onnx.main([str(tmp_path / "toy" / "model_0.pt"), "-o", str(toy)])
    cases = {
        (str(toy), "--mujoco"): "deploy metadata",
        (WALK_ONNX, "--mujoco", "--preference", "0.7,0.7"): "sum to 1",
        (WALK_ONNX, "--network", "no-such-if0"): "names no network interface",
        (str(tmp_path / "missing.onnx"), "--mujoco"): "no policy file",
    }
    if not sdk_available():
        cases.pop((WALK_ONNX, "--network", "no-such-if0"))
    for args, expected in cases.items():
        done = run_cli(*args)
        assert done.returncode != 0
        lines = [line for line in done.stderr.strip().splitlines() if line]
        assert len(lines) == 1 and expected in lines[0], (args, done.stderr)


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


def test_the_browser_console_steers_a_deploy():
    """The console's widgets (set as the page sets them) reach the deploy loop: start, lambda, command, policy."""
    pytest.importorskip("viser")
    import socket

    from pchc_rsl.deploy.web_console import DeployConsole

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    console = DeployConsole(["disturbance", "stride"], [0.5, 0.5], 0.5, port=port)
    try:
        robot = FakeRobot()
        run = fake_deployment(robot)
        run.auto = None  # only the console drives it
        run.inputs = [console]
        run.tick()
        assert run.safety.mode is Mode.ZERO_TORQUE
        console.buttons["s"].value = True  # a click
        run.tick()
        assert run.safety.mode is Mode.RAMP
        console.preference_sliders[0].value = 0.8
        console.command_slider.value = 0.3
        for _ in range(int(RAMP_S / 0.02) + 2):
            robot.wait_tick()
            run.tick()
        assert run.preference.value.tolist() == pytest.approx([0.2, 0.8]) and run.command.value[0] == 0.3
        console.buttons["p"].value = True
        run.tick()
        assert run.safety.mode is Mode.POLICY
        for _ in range(15):  # the console's status is refreshed 4 times a second
            robot.wait_tick()
            run.tick()
        assert "policy" in console.status.content and "stride **0.80**" in console.preference_text.content
    finally:
        console.close()
