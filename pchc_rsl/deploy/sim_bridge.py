"""The MuJoCo DDS bridge: the simulated G1 speaks rt/lowcmd and rt/lowstate like the robot, in real time, so that
pchc-deploy runs unchanged against it before it runs against a G1 (sim-to-sim)."""

from __future__ import annotations

import contextlib
import json
import os
import threading
import time

from pchc_rsl.deploy.fixed_rate import FixedRateLoop
from pchc_rsl.deploy.real_time import REAL_TIME_BOUND
from pchc_rsl.deploy.robot_io import Remote
from pchc_rsl.deploy.simulator import G1Simulator
from pchc_rsl.viewers.passive import passive_viewer

G1_MODE_MACHINE = 5
"""What a 29-DoF G1 reports as mode_machine (a deploy must echo it in LowCmd or the robot ignores the command)."""


class SimBridge:
    """Physics at the model's timestep on a fixed-rate loop; each step applies the newest command that has
    arrived (the motors' PD recomputed every step) and publishes the state."""

    def __init__(self, sim: G1Simulator, dds_end_factory, remote: Remote | None = None, viewer: bool = False,
                 parent_pid: int | None = None) -> None:
        """``parent_pid``: stop when that process is gone (pchc-deploy --sim starts the bridge and may be killed)."""
        self.sim = sim
        self.remote = remote or Remote()
        self._lock = threading.Lock()
        self.dds = dds_end_factory(self._on_command)
        self.loop = FixedRateLoop(float(sim.model.opt.timestep))
        self.stop = threading.Event()
        self.viewer = viewer
        self.parent_pid = parent_pid
        self.slowest_step_s = 0.0
        self.started: float | None = None
        self.stopped: float | None = None

    def _on_command(self, cmd) -> None:
        with self._lock:
            self.sim.apply(cmd)

    def run(self, seconds: float | None = None) -> None:
        end = None if seconds is None else time.monotonic() + seconds
        opened = passive_viewer(self.sim.model, self.sim.data) if self.viewer else contextlib.nullcontext()
        self.started = time.monotonic()
        with opened as viewer:
            while not self.stop.is_set() and (end is None or time.monotonic() < end):
                began = time.monotonic()
                with self._lock:
                    self.sim.step()
                    state = self.sim.state()
                state.remote = self.remote.encode()
                self.dds.publish(state, G1_MODE_MACHINE)
                if viewer is not None and self.sim.steps % 17 == 0:  # about 30 frames per second
                    viewer.sync()
                if self.parent_pid is not None and self.sim.steps % 100 == 0 and os.getppid() != self.parent_pid:
                    break
                self.slowest_step_s = max(self.slowest_step_s, time.monotonic() - began)
                self.loop.wait()
        self.stopped = time.monotonic()

    def real_time(self) -> dict:
        """How well the physics kept up with the wall clock: simulated / wall time, share of late steps, the
        slowest step's own duration."""
        wall = (self.stopped or time.monotonic()) - self.started if self.started is not None else 0.0
        factor = self.sim.time / wall if wall > 0 else 1.0
        return {"real_time_factor": round(factor, 3), "late_share": round(self.loop.overruns / max(1, self.loop.ticks), 4),
                "slowest_step_ms": round(self.slowest_step_s * 1e3, 2), "wall_s": round(wall, 3),
                "kept_real_time": bool(factor >= REAL_TIME_BOUND)}

    def report(self) -> dict:
        return {"fell": bool(self.sim.fell), "base_distance": round(self.sim.driven_distance(), 4),
                "fell_at": self.sim.fell_at, "damped_at": self.sim.damped_at,
                "base_position": [round(float(x), 4) for x in self.sim.base_position()],
                "sim_time": round(self.sim.time, 4), "commands_received": self.dds.received,
                "commands_bad_crc": self.dds.bad_crc, "commands_rejected": self.dds.rejected,
                "states_sent": self.dds.sent, "loop": self.loop.summary(), "pd_on_arrival": self.sim.pd_on_arrival,
                "timestep": float(self.sim.model.opt.timestep), "min_height_after_release": self.sim.min_height_after_release,
                "band_force_left": self.sim.band_force_left,
                "pose_trace": [[round(v, 4) for v in row] for row in self.sim.trace],
                **self.real_time()}

    def write_report(self, path: str) -> None:
        with open(path, "w") as f:
            json.dump(self.report(), f, indent=1)
