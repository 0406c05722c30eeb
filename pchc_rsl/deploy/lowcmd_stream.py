"""LowCmd at the robot's low-level rate, apart from the policy's rate.

A G1's motors, and Unitree's own low-level examples (unitree_sdk2_python example/g1/low_level: 2 ms), take a LowCmd
every 2 ms; a simulator that computes the torque when a command arrives (unitree_mujoco) runs the PD law only as
often as commands come. So the policy loop sets the newest command and this thread writes it on a fixed grid of the
monotonic clock, 500 times a second by default, each message the newest command with its CRC.

If the control loop stops setting commands for ``stall_s`` (a hung process, not a slow tick), the stream writes
damping instead of repeating the last policy targets forever.
"""

from __future__ import annotations

import os
import threading
import time

from pchc_rsl.deploy.fixed_rate import FixedRateLoop
from pchc_rsl.deploy.robot_io import MotorCommand

DEFAULT_LOWCMD_HZ = 500.0
MAX_LOWCMD_HZ = 1000.0
STALL_S = 0.5
"""Seconds without a new command from the control loop (25 of its 50 Hz periods) before the stream damps."""


def check_lowcmd_rate(rate_hz: float, policy_hz: float) -> None:
    """Between the policy's own rate (each command written at least once) and 1000 Hz (twice the robot's rate)."""
    if not policy_hz - 1e-6 <= rate_hz <= MAX_LOWCMD_HZ:
        raise ValueError(f"--lowcmd-hz {rate_hz:g} is outside [{policy_hz:g}, {MAX_LOWCMD_HZ:g}]: at least the "
                         f"policy's rate ({policy_hz:g} Hz), at most {MAX_LOWCMD_HZ:g} Hz; a G1 takes 500 (the default).")


STREAM_PRIORITY = 20
"""SCHED_FIFO priority of the stream's thread where the process may take it (root or CAP_SYS_NICE): on a busy
computer a thread of normal priority wakes up late often enough to lose one message in five. The thread sleeps
between messages and writes for about 0.1 ms, so it takes little from anything else."""


def raise_priority() -> bool:
    """Real-time (SCHED_FIFO) scheduling for the calling thread; False (and unchanged) where not permitted."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(STREAM_PRIORITY))
    except (OSError, AttributeError):
        return False
    return True


class LowCmdStream:
    """``set(cmd)`` from the control loop; a thread calls ``write(cmd)`` at ``rate_hz`` with the newest one."""

    def __init__(self, write, rate_hz: float = DEFAULT_LOWCMD_HZ, damping_kd: float = 8.0,
                 stall_s: float = STALL_S) -> None:
        self.write, self.stall_s = write, stall_s
        self.loop = FixedRateLoop(1.0 / rate_hz)
        self.damping = MotorCommand()
        self.damping.kd[:] = damping_kd
        self._lock = threading.Lock()
        self._latest: MotorCommand | None = None
        self._set_at = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.sent = self.stalls = 0
        self.error = ""
        self.realtime = False

    def set(self, cmd: MotorCommand) -> None:
        with self._lock:
            self._latest, self._set_at = cmd, time.monotonic()
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="lowcmd-stream", daemon=True)
            self._thread.start()

    def _run(self) -> None:
        self.realtime = raise_priority()
        stalled = False
        while not self._stop.is_set():
            with self._lock:
                cmd, age = self._latest, time.monotonic() - self._set_at
            if age > self.stall_s and not cmd.is_damping():
                if not stalled:
                    self.stalls += 1
                stalled, cmd = True, self.damping
            else:
                stalled = False
            try:
                self.write(cmd)
            except Exception as error:  # noqa: BLE001 - a failed write is reported, the stream goes on
                self.error = f"{type(error).__name__}: {error}"
            else:
                self.sent += 1
            self.loop.wait()

    def close(self) -> None:
        """Stop after the message being written (the control loop has already set damping)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)

    def summary(self) -> dict:
        return {"rate_hz": round(1.0 / self.loop.period, 3), "sent": self.sent, "stalls": self.stalls,
                "realtime_priority": self.realtime,
                **{f"loop_{k}": v for k, v in self.loop.summary().items()}} | ({"error": self.error} if self.error else {})

