"""Everything that touches unitree_sdk2py (the official Python SDK over CycloneDDS) is in this module, so that a
user's own SDK install serves as well as the ``pchc-rsl[deploy]`` extra: hg LowCmd/LowState conversion, the CRC,
and the two ends of rt/lowcmd and rt/lowstate (the deploy's and the sim bridge's)."""

from __future__ import annotations

import threading
import time

import numpy as np

from pchc_rsl.deploy.g1_motors import NUM_MOTORS
from pchc_rsl.deploy.robot_io import MotorCommand, RobotState

LOWCMD_TOPIC = "rt/lowcmd"
LOWSTATE_TOPIC = "rt/lowstate"
MOTOR_SLOTS = 35
"""hg messages carry 35 motor slots; a 29-DoF G1 uses the first 29."""


class SdkMissing(ImportError):
    """unitree_sdk2py (and CycloneDDS) are not installed."""


def sdk():
    """The SDK's modules, or one line naming the extra."""
    try:
        from unitree_sdk2py.core import channel
        from unitree_sdk2py.idl import default
        from unitree_sdk2py.idl.unitree_hg.msg import dds_ as hg
        from unitree_sdk2py.utils.crc import CRC
    except ImportError as error:
        raise SdkMissing(f"unitree_sdk2py is not importable ({error}); install the deploy extra: "
                         "pip install -e \".[deploy]\" (or Unitree's unitree_sdk2_python)") from None
    return channel, default, hg, CRC


def start_dds(domain: int, interface: str | None) -> None:
    """Join DDS domain ``domain`` on ``interface`` (None: CycloneDDS picks one); once per process."""
    channel, *_ = sdk()
    if interface is not None:
        import socket

        names = [name for _, name in socket.if_nameindex()]
        if interface not in names:
            raise ValueError(f"--network {interface} names no network interface here; this machine has "
                             f"{', '.join(names)} (the G1's is usually the one on 192.168.123.x).")
    channel.ChannelFactoryInitialize(domain, interface)


def crc_of(message) -> int:
    """The CRC32 that a G1 checks (the SDK's own routine, over the message packed as the robot packs it)."""
    *_, CRC = sdk()
    return CRC().Crc(message)


def lowcmd_message(cmd: MotorCommand, mode_machine: int, mode_pr: int = 0):
    """An hg LowCmd_ for ``cmd`` (motors 29-34 off) with its CRC."""
    _, default, _, _ = sdk()
    msg = default.unitree_hg_msg_dds__LowCmd_()
    msg.mode_pr, msg.mode_machine = int(mode_pr), int(mode_machine)
    for i in range(NUM_MOTORS):
        m = msg.motor_cmd[i]
        m.mode, m.q, m.dq = int(cmd.mode[i]), float(cmd.q[i]), float(cmd.dq[i])
        m.kp, m.kd, m.tau = float(cmd.kp[i]), float(cmd.kd[i]), float(cmd.tau[i])
    msg.crc = crc_of(msg)
    return msg


def command_of(msg) -> MotorCommand:
    motors = msg.motor_cmd[:NUM_MOTORS]
    return MotorCommand(q=np.array([m.q for m in motors]), dq=np.array([m.dq for m in motors]),
                        kp=np.array([m.kp for m in motors]), kd=np.array([m.kd for m in motors]),
                        tau=np.array([m.tau for m in motors]), mode=np.array([m.mode for m in motors], np.uint8))


def lowstate_message(state: RobotState, mode_machine: int):
    _, default, _, _ = sdk()
    msg = default.unitree_hg_msg_dds__LowState_()
    msg.tick, msg.mode_machine = int(state.tick) & 0xFFFFFFFF, int(mode_machine)
    msg.imu_state.quaternion = [float(x) for x in state.quat]
    msg.imu_state.gyroscope = [float(x) for x in state.gyro]
    for i in range(NUM_MOTORS):
        m = msg.motor_state[i]
        m.mode, m.q, m.dq, m.tau_est = 1, float(state.q[i]), float(state.dq[i]), float(state.tau[i])
    msg.wireless_remote = list(state.remote)
    msg.crc = crc_of(msg)
    return msg


def state_of(msg, received_at: float) -> RobotState:
    motors = msg.motor_state[:NUM_MOTORS]
    return RobotState(q=np.array([m.q for m in motors]), dq=np.array([m.dq for m in motors]),
                      tau=np.array([m.tau_est for m in motors]), quat=np.array(msg.imu_state.quaternion, float),
                      gyro=np.array(msg.imu_state.gyroscope, float), tick=int(msg.tick),
                      mode_machine=int(msg.mode_machine), remote=bytes(msg.wireless_remote), received_at=received_at)


class DdsRobot:
    """The deploy's end: the latest rt/lowstate (converted on arrival) and rt/lowcmd out, with counters."""

    def __init__(self, domain: int, interface: str | None) -> None:
        channel, _, hg, _ = sdk()
        start_dds(domain, interface)
        self.domain, self.interface = domain, interface
        self._lock = threading.Lock()
        self._state: RobotState | None = None
        self.received = self.sent = 0
        self._publisher = channel.ChannelPublisher(LOWCMD_TOPIC, hg.LowCmd_)
        self._publisher.Init()
        self._subscriber = channel.ChannelSubscriber(LOWSTATE_TOPIC, hg.LowState_)
        self._subscriber.Init(self._on_state, 10)

    def _on_state(self, msg) -> None:
        state = state_of(msg, time.monotonic())
        with self._lock:
            self._state = state
            self.received += 1

    def read(self) -> RobotState | None:
        with self._lock:
            return self._state

    def send(self, cmd: MotorCommand) -> None:
        state = self.read()
        self._publisher.Write(lowcmd_message(cmd, state.mode_machine if state is not None else 0))
        self.sent += 1

    def close(self) -> None:
        self._subscriber.Close()
        self._publisher.Close()


class DdsBridgeEnd:
    """The sim bridge's end: rt/lowcmd in (CRC checked, bad ones dropped and counted), rt/lowstate out."""

    def __init__(self, domain: int, interface: str | None, on_command) -> None:
        channel, _, hg, _ = sdk()
        start_dds(domain, interface)
        self.on_command = on_command
        self.received = self.bad_crc = self.sent = 0
        self._publisher = channel.ChannelPublisher(LOWSTATE_TOPIC, hg.LowState_)
        self._publisher.Init()
        self._subscriber = channel.ChannelSubscriber(LOWCMD_TOPIC, hg.LowCmd_)
        self._subscriber.Init(self._on_command, 10)

    def _on_command(self, msg) -> None:
        if crc_of(msg) != msg.crc:
            self.bad_crc += 1
            return
        self.received += 1
        self.on_command(command_of(msg))

    def publish(self, state: RobotState, mode_machine: int) -> None:
        self._publisher.Write(lowstate_message(state, mode_machine))
        self.sent += 1

    def close(self) -> None:
        self._subscriber.Close()
        self._publisher.Close()
