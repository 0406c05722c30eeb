"""hg LowCmd and LowState as bytes, written with numpy: the packed C layout a G1 computes its CRC over, the CRC
itself, and the CDR encoding DDS carries.

Why not the SDK's own routines: cyclonedds's Python serializer and unitree_sdk2py's CRC packing cost about 1-2 ms
per message each on a busy 2-core machine, too much for LowCmd at 500 Hz or LowState at every 2 ms physics step.
These produce the same bytes (tests compare them with the SDK's CRC and cyclonedds's serializer, byte for byte).
"""

from __future__ import annotations

import ctypes
import functools

import numpy as np

MOTOR_SLOTS = 35

_MOTOR_CMD = np.dtype({"names": ["mode", "q", "dq", "tau", "kp", "kd", "reserve"],
                       "formats": ["u1", "<f4", "<f4", "<f4", "<f4", "<f4", "<u4"],
                       "offsets": [0, 4, 8, 12, 16, 20, 24], "itemsize": 28})
LOWCMD_LAYOUT = np.dtype({"names": ["mode_pr", "mode_machine", "motor_cmd", "reserve", "crc"],
                          "formats": ["u1", "u1", (_MOTOR_CMD, MOTOR_SLOTS), ("<u4", 4), "<u4"],
                          "offsets": [0, 1, 4, 984, 1000], "itemsize": 1004})
"""unitree_hg LowCmd_ as the robot packs it for its CRC: '<2B2x' + 'B3x5fI' * 35 + '5I' (1004 bytes)."""

_MOTOR_STATE = np.dtype({"names": ["mode", "q", "dq", "ddq", "tau_est", "temperature", "vol", "sensor", "motorstate",
                                   "reserve"],
                         "formats": ["u1", "<f4", "<f4", "<f4", "<f4", ("<i2", 2), "<f4", ("<u4", 2), "<u4",
                                     ("<u4", 4)],
                         "offsets": [0, 4, 8, 12, 16, 20, 24, 28, 36, 40], "itemsize": 56})
_IMU = np.dtype({"names": ["quaternion", "gyroscope", "accelerometer", "rpy", "temperature"],
                 "formats": [("<f4", 4), ("<f4", 3), ("<f4", 3), ("<f4", 3), "<i2"],
                 "offsets": [0, 16, 28, 40, 52], "itemsize": 56})
LOWSTATE_LAYOUT = np.dtype({"names": ["version", "mode_pr", "mode_machine", "tick", "imu_state", "motor_state",
                                      "wireless_remote", "reserve", "crc"],
                            "formats": [("<u4", 2), "u1", "u1", "<u4", _IMU, (_MOTOR_STATE, MOTOR_SLOTS), ("u1", 40),
                                        ("<u4", 4), "<u4"],
                            "offsets": [0, 8, 9, 12, 16, 72, 2032, 2072, 2088], "itemsize": 2092})
"""unitree_hg LowState_ as the robot packs it for its CRC: '<2I2B2xI' + '13fh2x' + 'B3x4f2hf7I' * 35 + '40B5I'."""

CDR_HEADER = b"\x00\x01\x00\x00"
"""XCDR1, little-endian: what cyclonedds puts before every sample of these types."""


def _crc_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte << 24
        for _ in range(8):
            crc = ((crc << 1) ^ 0x04C11DB7) if crc & 0x80000000 else crc << 1
        table.append(crc & 0xFFFFFFFF)
    return table


@functools.cache
def _native_crc():
    """unitree_sdk2py's compiled crc32_core, or None (then the table-driven Python version below)."""
    try:
        from unitree_sdk2py.utils.crc import CRC

        core = CRC().crc_lib.crc32_core
    except (ImportError, AttributeError, OSError):
        return None
    core.argtypes = (ctypes.c_void_p, ctypes.c_uint32)
    core.restype = ctypes.c_uint32
    return core


def crc32(packed: np.ndarray) -> int:
    """Unitree's crc32_core over every 32-bit word of ``packed`` but the last (the CRC's own slot): polynomial
    0x04C11DB7, MSB first, initial 0xFFFFFFFF, no final xor (the same as CRC-32/MPEG-2 over each word's bytes
    taken big-endian)."""
    words = np.ascontiguousarray(packed).view("<u4").reshape(-1)[:-1]
    core = _native_crc()
    if core is not None:
        return int(core(words.ctypes.data, len(words)))
    table, crc = _TABLE, 0xFFFFFFFF
    for byte in words.astype(">u4").tobytes():
        crc = ((crc << 8) & 0xFFFFFFFF) ^ table[(crc >> 24) ^ byte]
    return crc


_TABLE = _crc_table()


def lowcmd_cdr(packed: np.ndarray) -> bytes:
    """The CDR sample of a packed LowCmd: the C layout's padding differs only before the first motor's floats
    (CDR aligns motor 0's mode byte to 1, C to 4)."""
    raw = packed.tobytes()
    return CDR_HEADER + raw[0:2] + raw[4:5] + raw[7:]


def lowstate_cdr(packed: np.ndarray) -> bytes:
    """The CDR sample of a packed LowState (as lowcmd_cdr: only the padding before motor 0's floats differs)."""
    raw = packed.tobytes()
    return CDR_HEADER + raw[0:70] + raw[72:73] + raw[75:]


def _padding(layout: np.dtype) -> np.ndarray:
    """[itemsize] bool: the bytes of ``layout`` that no field covers."""
    covered = np.zeros(layout.itemsize, bool)

    def mark(dtype: np.dtype, offset: int) -> None:
        if dtype.subdtype is not None:
            base, shape = dtype.subdtype
            for k in range(int(np.prod(shape))):
                mark(base, offset + k * base.itemsize)
        elif dtype.names:
            for name in dtype.names:
                field, at = dtype.fields[name][:2]
                mark(field, offset + at)
        else:
            covered[offset:offset + dtype.itemsize] = True

    mark(layout, 0)
    return ~covered


_LOWCMD_PADDING = _padding(LOWCMD_LAYOUT)
_LOWSTATE_PADDING = _padding(LOWSTATE_LAYOUT)


def _packed(raw: bytes, layout: np.dtype, padding: np.ndarray) -> np.ndarray:
    buf = np.frombuffer(raw, np.uint8).copy()
    buf[padding] = 0  # the CRC is computed with zero padding, whatever a sender left there
    return buf.view(layout)


def _body(sample: bytes, kind: str, size: int) -> bytes:
    if bytes(sample[:2]) != CDR_HEADER[:2]:
        raise ValueError(f"a {kind} encoded as {bytes(sample[:2]).hex()} arrived; this reads little-endian XCDR1 "
                         f"(header {CDR_HEADER[:2].hex()}), as unitree_sdk2 writes it.")
    body = bytes(sample[4:])
    if len(body) != size:
        raise ValueError(f"a {kind} of {len(sample) - 4} bytes arrived; a G1's unitree_hg {kind} with "
                         f"{MOTOR_SLOTS} motor slots has {size}. Is another robot on this DDS domain? Check "
                         "--network and --domain.")
    return body


def lowcmd_from_cdr(sample: bytes) -> np.ndarray:
    """[1] LOWCMD_LAYOUT from a LowCmd's CDR sample (the inverse of lowcmd_cdr, padding zeroed)."""
    body = _body(sample, "LowCmd", LOWCMD_LAYOUT.itemsize - 4)
    return _packed(body[0:2] + bytes(2) + body[2:3] + bytes(3) + body[4:], LOWCMD_LAYOUT, _LOWCMD_PADDING)


def lowstate_from_cdr(sample: bytes) -> np.ndarray:
    """[1] LOWSTATE_LAYOUT from a LowState's CDR sample (the inverse of lowstate_cdr, padding zeroed)."""
    body = _body(sample, "LowState", LOWSTATE_LAYOUT.itemsize - 4)
    return _packed(body[0:70] + bytes(2) + body[70:71] + bytes(3) + body[72:], LOWSTATE_LAYOUT, _LOWSTATE_PADDING)
