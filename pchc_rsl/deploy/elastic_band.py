"""unitree_mujoco's elastic band, the gantry of its simulate_python: a spring-damper from a point 3 m above the
origin to the torso, 200 N/m and 100 N s/m, of rest length 0, lengthened 0.1 m by each press of key 8 and let go by
key 9 (``ElasticBand`` in their unitree_sdk2py_bridge.py, applied to torso_link in unitree_mujoco.py).

Their loop writes the band's force into ``xfrc_applied`` only while the band is on, and MuJoCo never clears it: in a
loop without their viewer the last force stays applied after the release, for good. Their viewer thread hides this:
``viewer.sync()`` clears ``xfrc_applied`` (MuJoCo's passive viewer does so at every sync). The force left depends on
how far the band was lowered: about 200 N upward after 12 presses, on a 35 kg robot."""

from __future__ import annotations

import numpy as np

STIFFNESS = 200.0
"""N/m."""
DAMPING = 100.0
"""N s/m, along the band."""
ANCHOR = np.array([0.0, 0.0, 3.0])
"""m, world frame."""
PRESS_LENGTH = 0.1
"""m the band lengthens per press of their key 8."""
PRESS_INTERVAL = 0.2
"""s between two presses, as an operator presses the key."""


def band_force(position: np.ndarray, velocity: np.ndarray, length: float) -> np.ndarray:
    """Force [3] (N, world frame) on the torso at ``position`` moving at ``velocity`` (their ``Advance``, which is
    given the free joint's position and linear velocity)."""
    delta = ANCHOR - np.asarray(position, float)
    distance = float(np.linalg.norm(delta))
    direction = delta / distance
    return (STIFFNESS * (distance - length) - DAMPING * float(np.dot(velocity, direction))) * direction


class UnitreeBand:
    """The band lowered by ``presses`` presses of key 8, ``PRESS_INTERVAL`` apart, the last one that long before it
    lets go at ``release_s``; ``force_stays``: its last force stays applied after the release, as in their loop
    without the viewer."""

    def __init__(self, presses: int, release_s: float, force_stays: bool = False) -> None:
        if presses < 0:
            raise ValueError(f"the band is lowered by a number of presses >= 0, got {presses}")
        self.presses, self.release_s, self.force_stays = presses, release_s, force_stays
        self.press_times = release_s - PRESS_INTERVAL * np.arange(presses, 0, -1)

    def length(self, t: float) -> float:
        """The band's rest length (m) at time ``t``: 0.1 m per press made by then."""
        return PRESS_LENGTH * int(np.count_nonzero(self.press_times <= t + 1e-9))

    def on(self, t: float) -> bool:
        return t < self.release_s

    def force(self, t: float, position: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        return band_force(position, velocity, self.length(t))
