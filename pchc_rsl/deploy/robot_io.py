"""What travels between a deploy and a G1, independent of the transport: the robot's state (as rt/lowstate carries
it) and one command per motor (as rt/lowcmd carries it), plus the wireless remote's 40 bytes."""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

from pchc_rsl.deploy.g1_motors import NUM_MOTORS

REMOTE_BUTTONS = ["R1", "L1", "start", "select", "R2", "L2", "F1", "F2", "A", "B", "X", "Y",
                  "up", "right", "down", "left"]
"""Bits 0-15 of the remote's key word (bytes 2-3 of LowState.wireless_remote, little-endian), Unitree's layout."""


@dataclass
class RobotState:
    """One rt/lowstate sample in SI units, motors in unitree_sdk2's order."""

    q: np.ndarray  # [29] rad
    dq: np.ndarray  # [29] rad/s
    tau: np.ndarray  # [29] Nm, estimated
    quat: np.ndarray  # [4] w, x, y, z of the pelvis IMU in the world
    gyro: np.ndarray  # [3] rad/s in the IMU (pelvis) frame
    tick: int = 0
    mode_machine: int = 0
    remote: bytes = bytes(40)
    received_at: float = 0.0  # time.monotonic() when it arrived

    def projected_gravity(self) -> np.ndarray:
        """Gravity's direction in the pelvis frame, as the policy saw it in training."""
        w, x, y, z = self.quat
        v = np.array([0.0, 0.0, -1.0])
        xyz = np.array([x, y, z])
        t = 2.0 * np.cross(xyz, v)
        return v - w * t + np.cross(xyz, t)


@dataclass
class MotorCommand:
    """One rt/lowcmd: per motor a PD target and gains plus a feed-forward torque; mode 1 enables the motor."""

    q: np.ndarray = field(default_factory=lambda: np.zeros(NUM_MOTORS))
    dq: np.ndarray = field(default_factory=lambda: np.zeros(NUM_MOTORS))
    kp: np.ndarray = field(default_factory=lambda: np.zeros(NUM_MOTORS))
    kd: np.ndarray = field(default_factory=lambda: np.zeros(NUM_MOTORS))
    tau: np.ndarray = field(default_factory=lambda: np.zeros(NUM_MOTORS))
    mode: np.ndarray = field(default_factory=lambda: np.ones(NUM_MOTORS, dtype=np.uint8))

    def is_damping(self) -> bool:
        """kp 0 and kd > 0 on every enabled motor: the safe state a deploy ends in."""
        on = self.mode > 0
        return bool(on.any() and (self.kp[on] == 0).all() and (self.kd[on] > 0).all())

    def torque(self, q: np.ndarray, dq: np.ndarray, limit: np.ndarray) -> np.ndarray:
        """What a G1 motor applies for this command at (q, dq): the PD law plus tau, clipped; 0 where disabled."""
        tau = self.kp * (self.q - q) + self.kd * (self.dq - dq) + self.tau
        return np.where(self.mode > 0, np.clip(tau, -limit, limit), 0.0)


@dataclass
class Remote:
    """The wireless remote as LowState carries it: buttons by name and the four stick axes in [-1, 1]."""

    buttons: frozenset = frozenset()
    lx: float = 0.0
    ly: float = 0.0
    rx: float = 0.0
    ry: float = 0.0

    @classmethod
    def parse(cls, data: bytes) -> "Remote":
        data = bytes(data)
        if len(data) < 24:
            return cls()
        keys = struct.unpack_from("<H", data, 2)[0]
        lx, rx, ry = struct.unpack_from("<3f", data, 4)
        ly = struct.unpack_from("<f", data, 20)[0]
        return cls(frozenset(b for i, b in enumerate(REMOTE_BUTTONS) if keys >> i & 1), lx, ly, rx, ry)

    def encode(self) -> bytes:
        """The 40 bytes a G1 would publish for this remote state (the sim bridge and tests send it)."""
        data = bytearray(40)
        keys = sum(1 << i for i, b in enumerate(REMOTE_BUTTONS) if b in self.buttons)
        struct.pack_into("<H", data, 2, keys)
        struct.pack_into("<3f", data, 4, self.lx, self.rx, self.ry)
        struct.pack_into("<f", data, 20, self.ly)
        return bytes(data)
