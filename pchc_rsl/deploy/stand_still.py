"""Whether the robot stands still in HOLD, from its IMU alone: a walker started while the robot still sways (after a
band or a gantry lets go) can step into another gait, so the policy starts only once the robot stands still
(docs/deploy.md, "The policy waits for a robot that stands still").

Still means the gyro's norm and the pelvis's tilt rate both below their bounds at every sample of a whole WINDOW_S.
The window is half the sway's period (about 2 s in both G1 models): a shorter one could fit between two peaks of a
sway, at its slow turning point. A sample above either bound (a sway, a push, a noise spike) starts the window
again."""

from __future__ import annotations

import numpy as np

GYRO_BOUND = 0.05
"""rad/s, the norm of the IMU's angular velocity. After unitree_mujoco's band lets go of their G1 model it reads up
to 0.23 rad/s in the second before 2 s (a walker started then turned circles), 0.12 before 4 s and 0.04 before 6 s;
the G1 let go by menagerie's stiff gantry reads at most 0.045 rad/s."""
TILT_RATE_BOUND = 0.05
"""1/s, how fast gravity's horizontal part in the pelvis frame changes (rad/s of tilt for small tilts): the sway
seen through the IMU's orientation rather than its gyro; it reads as the gyro does in a sway fore and aft."""
WINDOW_S = 1.0
"""s both must stay below their bounds."""


def tilt_rate(gravity_before: np.ndarray, gravity_now: np.ndarray, dt: float) -> float:
    """How fast the pelvis tilts (1/s): the change of gravity's horizontal part in the pelvis frame [3] over ``dt``."""
    return float(np.linalg.norm(np.asarray(gravity_now)[:2] - np.asarray(gravity_before)[:2]) / dt)


class StandStill:
    """``update(now, gyro, gravity)`` with each state in HOLD; ``still`` once both signals stayed below their bounds
    for ``window_s``. ``reset()`` when HOLD ends."""

    def __init__(self, gyro_bound: float = GYRO_BOUND, tilt_rate_bound: float = TILT_RATE_BOUND,
                 window_s: float = WINDOW_S) -> None:
        self.gyro_bound, self.tilt_rate_bound, self.window_s = gyro_bound, tilt_rate_bound, window_s
        self.reset()

    def reset(self) -> None:
        self.since: float | None = None  # the first sample of the current run below both bounds
        self.gyro = self.tilt_rate = 0.0  # the latest sample's
        self._last: tuple[float, np.ndarray] | None = None  # (time, gravity) of the previous sample
        self.now = 0.0

    def update(self, now: float, gyro: np.ndarray, gravity: np.ndarray) -> bool:
        """One sample: ``gyro`` [3] rad/s and ``gravity`` [3] (gravity's direction in the pelvis frame) at time
        ``now`` (s). The first sample has no tilt rate yet; its gyro alone decides. Returns ``still``."""
        gravity = np.asarray(gravity, float)
        self.gyro = float(np.linalg.norm(gyro))
        if self._last is not None and now > self._last[0]:
            self.tilt_rate = tilt_rate(self._last[1], gravity, now - self._last[0])
        self._last, self.now = (now, gravity), now
        if self.gyro < self.gyro_bound and self.tilt_rate < self.tilt_rate_bound:
            if self.since is None:
                self.since = now
        else:
            self.since = None
        return self.still

    @property
    def still(self) -> bool:
        return self.since is not None and self.now - self.since >= self.window_s - 1e-9

    def __str__(self) -> str:
        """The latest sample against the bounds, for the operator."""
        return (f"gyro {self.gyro:.3f} rad/s (bound {self.gyro_bound:g}), tilt rate {self.tilt_rate:.3f}/s (bound "
                f"{self.tilt_rate_bound:g}), for {self.window_s:g} s")
