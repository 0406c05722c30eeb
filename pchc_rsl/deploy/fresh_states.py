"""How many LowState messages carried a new reading. A simulator whose physics runs behind its LowState timer
(unitree_mujoco publishes from a timer thread of its own) sends its last state again, so the rate of messages
alone does not show its pace; the rate of new readings does. A robot's sensors never repeat a reading exactly."""

from __future__ import annotations

import numpy as np

from pchc_rsl.deploy.robot_io import RobotState


def same_reading(a: RobotState, b: RobotState) -> bool:
    """Every sensor value equal: joints (position, velocity, torque) and IMU (orientation, gyro). The tick is left
    out, as a simulator's timer may count it up while its physics stands."""
    return all(np.array_equal(getattr(a, name), getattr(b, name)) for name in ("q", "dq", "tau", "quat", "gyro"))


class FreshStates:
    """``add(state)`` for each LowState as it arrives; counts them, the new readings among them, and the time from
    the first to the last (by ``received_at``)."""

    def __init__(self) -> None:
        self.received = self.fresh = 0
        self.first_at: float | None = None
        self.last_at: float | None = None
        self._last: RobotState | None = None

    def add(self, state: RobotState) -> bool:
        """Count ``state``; True if its reading differs from the one before."""
        new = self._last is None or not same_reading(self._last, state)
        self.received += 1
        self.fresh += new
        self._last = state
        if self.first_at is None:
            self.first_at = state.received_at
        self.last_at = state.received_at
        return new

    @property
    def seconds(self) -> float:
        """From the first LowState to the last."""
        return 0.0 if self.first_at is None else self.last_at - self.first_at

    def summary(self) -> dict:
        return {"received": self.received, "fresh": self.fresh, "seconds": round(self.seconds, 3)}
