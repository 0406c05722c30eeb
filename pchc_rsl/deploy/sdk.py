"""Everything that touches unitree_sdk2py (the official Python SDK over CycloneDDS) is in this module, so that a
user's own SDK install serves as well as the ``pchc-rsl[deploy]`` extra: hg LowCmd/LowState conversion, the CRC,
and the two ends of rt/lowcmd and rt/lowstate (the deploy's and the sim bridge's)."""

from __future__ import annotations

import socket
import threading
import time

import numpy as np

from pchc_rsl.deploy.fresh_states import FreshStates
from pchc_rsl.deploy.g1_motors import NUM_MOTORS
from pchc_rsl.deploy.lowcmd_stream import DEFAULT_LOWCMD_HZ, LowCmdStream
from pchc_rsl.deploy.robot_io import MotorCommand, RobotState
from pchc_rsl.deploy.wire_format import (LOWCMD_LAYOUT, LOWSTATE_LAYOUT, crc32, lowcmd_cdr,
                                         lowcmd_from_cdr, lowstate_cdr, lowstate_from_cdr)

LOWCMD_TOPIC = "rt/lowcmd"
LOWSTATE_TOPIC = "rt/lowstate"


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
        names = [name for _, name in socket.if_nameindex()]
        if interface not in names:
            raise ValueError(f"--network {interface} names no network interface here; this machine has "
                             f"{', '.join(names)} (the G1's is usually the one on 192.168.123.x).")
    channel.ChannelFactoryInitialize(domain, interface)


def _sample(template, packed: np.ndarray, cdr: bytes):
    """An SDK message whose fields hold ``packed``'s values and whose DDS sample is ``cdr`` (cyclonedds writes what
    ``serialize`` returns; the numpy encoding is checked against its own serializer in the tests)."""
    template.crc = int(packed["crc"][0])
    idl_serialize = template.serialize

    def serialize(buffer=None, endianness=None, use_version_2=None) -> bytes:
        if buffer is None and endianness is None and not use_version_2:
            return cdr
        return idl_serialize(buffer=buffer, endianness=endianness, use_version_2=use_version_2)

    template.serialize = serialize
    return template


def pack_lowcmd(cmd: MotorCommand, mode_machine: int, mode_pr: int = 0) -> np.ndarray:
    """[1] LOWCMD_LAYOUT for ``cmd`` (motors 29-34 off), its CRC filled in."""
    packed = np.zeros(1, LOWCMD_LAYOUT)
    packed["mode_pr"], packed["mode_machine"] = int(mode_pr), int(mode_machine)
    motors = packed["motor_cmd"][0]
    for name in ("mode", "q", "dq", "tau", "kp", "kd"):
        motors[name][:NUM_MOTORS] = getattr(cmd, name)
    packed["crc"] = crc32(packed)
    return packed


def lowcmd_message(cmd: MotorCommand, mode_machine: int, mode_pr: int = 0):
    """An hg LowCmd_ for ``cmd`` (motors 29-34 off) with its CRC."""
    _, default, _, _ = sdk()
    packed = pack_lowcmd(cmd, mode_machine, mode_pr)
    msg = default.unitree_hg_msg_dds__LowCmd_()
    msg.mode_pr, msg.mode_machine = int(mode_pr), int(mode_machine)
    motors = packed["motor_cmd"][0]
    values = {name: motors[name][:NUM_MOTORS].tolist() for name in ("mode", "q", "dq", "tau", "kp", "kd")}
    for i in range(NUM_MOTORS):
        m = msg.motor_cmd[i]
        m.mode, m.q, m.dq = values["mode"][i], values["q"][i], values["dq"][i]
        m.tau, m.kp, m.kd = values["tau"][i], values["kp"][i], values["kd"][i]
    return _sample(msg, packed, lowcmd_cdr(packed))


def pack_lowstate(state: RobotState, mode_machine: int) -> np.ndarray:
    """[1] LOWSTATE_LAYOUT for ``state`` (motors 29-34 empty), its CRC filled in."""
    packed = np.zeros(1, LOWSTATE_LAYOUT)
    packed["tick"], packed["mode_machine"] = int(state.tick) & 0xFFFFFFFF, int(mode_machine)
    imu = packed["imu_state"]
    imu["quaternion"], imu["gyroscope"] = state.quat, state.gyro
    motors = packed["motor_state"][0]
    motors["mode"][:NUM_MOTORS] = 1
    motors["q"][:NUM_MOTORS], motors["dq"][:NUM_MOTORS], motors["tau_est"][:NUM_MOTORS] = state.q, state.dq, state.tau
    packed["wireless_remote"] = np.frombuffer(bytes(state.remote), np.uint8)
    packed["crc"] = crc32(packed)
    return packed


def lowstate_message(state: RobotState, mode_machine: int, fields: bool = True):
    """An hg LowState_ for ``state`` with its CRC. ``fields=False``: only the DDS sample is filled in (what the
    bridge publishes at every physics step; setting the fields costs as much again)."""
    _, default, _, _ = sdk()
    packed = pack_lowstate(state, mode_machine)
    msg = default.unitree_hg_msg_dds__LowState_()
    if fields:
        msg.tick, msg.mode_machine = int(packed["tick"][0]), int(mode_machine)
        msg.imu_state.quaternion = packed["imu_state"]["quaternion"][0].tolist()
        msg.imu_state.gyroscope = packed["imu_state"]["gyroscope"][0].tolist()
        motors = packed["motor_state"][0]
        q, dq, tau = (motors[name][:NUM_MOTORS].tolist() for name in ("q", "dq", "tau_est"))
        for i in range(NUM_MOTORS):
            m = msg.motor_state[i]
            m.mode, m.q, m.dq, m.tau_est = 1, q[i], dq[i], tau[i]
        msg.wireless_remote = list(bytes(state.remote))
    return _sample(msg, packed, lowstate_cdr(packed))


def command_of_packed(packed: np.ndarray) -> MotorCommand:
    motors = packed["motor_cmd"][0][:NUM_MOTORS]
    return MotorCommand(q=motors["q"].astype(float), dq=motors["dq"].astype(float), kp=motors["kp"].astype(float),
                        kd=motors["kd"].astype(float), tau=motors["tau"].astype(float), mode=motors["mode"].copy())


def state_of_packed(packed: np.ndarray, received_at: float) -> RobotState:
    motors = packed["motor_state"][0][:NUM_MOTORS]
    imu = packed["imu_state"][0]
    return RobotState(q=motors["q"].astype(float), dq=motors["dq"].astype(float), tau=motors["tau_est"].astype(float),
                      quat=imu["quaternion"].astype(float), gyro=imu["gyroscope"].astype(float),
                      tick=int(packed["tick"][0]), mode_machine=int(packed["mode_machine"][0]),
                      remote=packed["wireless_remote"][0].tobytes(), received_at=received_at)


class RawReader:
    """A subscription that hands each sample over as its CDR bytes, for wire_format to decode: cyclonedds's Python
    decoding of an hg message costs about 1 ms, as much as half a physics step, at 500 messages a second."""

    def __init__(self, domain: int, topic_name: str, idl_type, on_sample, depth: int = 64) -> None:
        from cyclonedds._clayer import ddspy_take
        from cyclonedds.core import InstanceState, Listener, SampleState, ViewState
        from cyclonedds.domain import DomainParticipant
        from cyclonedds.qos import Policy, Qos
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        mask = SampleState.Any | ViewState.Any | InstanceState.Any

        def on_data_available(reader) -> None:
            if reader is None:  # a sample that arrived while the reader was being deleted, at the end of a run
                return
            taken = ddspy_take(reader._ref, mask, depth)
            if isinstance(taken, int):
                return
            now = time.monotonic()
            for data, info in taken:
                if info.valid_data:
                    on_sample(data, now)

        self.participant = DomainParticipant(domain)
        self.topic = Topic(self.participant, topic_name, idl_type)
        self.reader = DataReader(self.participant, self.topic, Qos(Policy.History.KeepLast(depth)),
                                 Listener(on_data_available=on_data_available))

    def close(self) -> None:
        self.reader = self.topic = self.participant = None


class DdsRobot:
    """The deploy's end: the latest rt/lowstate (converted on arrival) and rt/lowcmd out at the low-level rate
    (LowCmdStream), with counters (``states``: LowState received, and how many were new readings). A LowState that
    is not a G1's (wrong size or encoding) is dropped, counted and its reason kept for the operator."""

    def __init__(self, domain: int, interface: str | None, lowcmd_hz: float = DEFAULT_LOWCMD_HZ,
                 damping_kd: float = 8.0) -> None:
        channel, _, hg, _ = sdk()
        start_dds(domain, interface)
        self.domain, self.interface = domain, interface
        self._lock = threading.Lock()
        self._state: RobotState | None = None
        self.states = FreshStates()
        self.rejected = self.commands = 0
        self.rejected_reason = ""
        self._publisher = channel.ChannelPublisher(LOWCMD_TOPIC, hg.LowCmd_)
        self._publisher.Init()
        self._encoded, self._encoded_for = None, (None, 0)
        self.stream = LowCmdStream(self._write, lowcmd_hz, damping_kd)
        self._subscriber = RawReader(domain, LOWSTATE_TOPIC, hg.LowState_, self._on_state)

    def _on_state(self, sample: bytes, received_at: float) -> None:
        try:
            state = state_of_packed(lowstate_from_cdr(sample), received_at)
        except ValueError as error:
            self.rejected += 1
            self.rejected_reason = str(error)
            return
        with self._lock:
            self._state = state
            self.states.add(state)

    def read(self) -> RobotState | None:
        with self._lock:
            return self._state

    @property
    def received(self) -> int:
        """LowState messages taken in."""
        return self.states.received

    def send(self, cmd: MotorCommand) -> None:
        """The control loop's newest command; the stream writes it until the next."""
        self.stream.set(cmd)
        self.commands += 1

    @property
    def sent(self) -> int:
        """LowCmd messages written."""
        return self.stream.sent

    def _write(self, cmd: MotorCommand) -> None:
        """Write ``cmd`` as a LowCmd with its CRC; encoded once per new command (or mode_machine), then the same
        bytes are written again until the next, which keeps 500 messages a second affordable on a busy machine."""
        state = self.read()
        mode_machine = state.mode_machine if state is not None else 0
        if cmd is not self._encoded_for[0] or mode_machine != self._encoded_for[1]:
            self._encoded, self._encoded_for = lowcmd_message(cmd, mode_machine), (cmd, mode_machine)
        self._publisher.Write(self._encoded)

    def close(self) -> None:
        self.stream.close()
        self._subscriber.close()
        self._publisher.Close()


class DdsBridgeEnd:
    """The sim bridge's end: rt/lowcmd in (CRC checked, bad ones dropped and counted), rt/lowstate out."""

    def __init__(self, domain: int, interface: str | None, on_command) -> None:
        channel, _, hg, _ = sdk()
        start_dds(domain, interface)
        self.on_command = on_command
        self.received = self.bad_crc = self.rejected = self.sent = 0
        self._publisher = channel.ChannelPublisher(LOWSTATE_TOPIC, hg.LowState_)
        self._publisher.Init()
        self._subscriber = RawReader(domain, LOWCMD_TOPIC, hg.LowCmd_, self._on_sample)

    def _on_sample(self, sample: bytes, received_at: float) -> None:
        try:
            packed = lowcmd_from_cdr(sample)
        except ValueError:
            self.rejected += 1
            return
        if crc32(packed) != int(packed["crc"][0]):
            self.bad_crc += 1
            return
        self.received += 1
        self.on_command(command_of_packed(packed))

    def publish(self, state: RobotState, mode_machine: int) -> None:
        self._publisher.Write(lowstate_message(state, mode_machine, fields=False))
        self.sent += 1

    def close(self) -> None:
        self._subscriber.close()
        self._publisher.Close()
