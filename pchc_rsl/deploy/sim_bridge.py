"""The MuJoCo DDS bridge: the simulated G1 speaks rt/lowcmd and rt/lowstate like the robot, in real time, so that
pchc-deploy runs unchanged against it before it runs against a G1 (sim-to-sim)."""

from __future__ import annotations

import contextlib
import json
import threading
import time

from pchc_rsl.deploy.fixed_rate import FixedRateLoop
from pchc_rsl.deploy.robot_io import Remote
from pchc_rsl.deploy.simulator import G1Simulator
from pchc_rsl.passive_viewer import passive_viewer

G1_MODE_MACHINE = 5
"""What a 29-DoF G1 reports as mode_machine (a deploy must echo it in LowCmd or the robot ignores the command)."""


class SimBridge:
    """Physics at the model's timestep on a fixed-rate loop; each step applies the newest command that has
    arrived (the motors' PD recomputed every step) and publishes the state."""

    def __init__(self, sim: G1Simulator, dds_end_factory, remote: Remote | None = None, viewer: bool = False) -> None:
        self.sim = sim
        self.remote = remote or Remote()
        self._lock = threading.Lock()
        self.dds = dds_end_factory(self._on_command)
        self.loop = FixedRateLoop(float(sim.model.opt.timestep))
        self.stop = threading.Event()
        self.viewer = viewer

    def _on_command(self, cmd) -> None:
        with self._lock:
            self.sim.apply(cmd)

    def run(self, seconds: float | None = None) -> None:
        end = None if seconds is None else time.monotonic() + seconds
        opened = passive_viewer(self.sim.model, self.sim.data) if self.viewer else contextlib.nullcontext()
        with opened as viewer:
            while not self.stop.is_set() and (end is None or time.monotonic() < end):
                with self._lock:
                    self.sim.step()
                    state = self.sim.state()
                state.remote = self.remote.encode()
                self.dds.publish(state, G1_MODE_MACHINE)
                if viewer is not None and self.sim.steps % 17 == 0:  # about 30 frames per second
                    viewer.sync()
                self.loop.wait()

    def report(self) -> dict:
        return {"fell": bool(self.sim.fell), "base_distance": round(self.sim.driven_distance(), 4),
                "fell_at": self.sim.fell_at, "damped_at": self.sim.damped_at,
                "base_position": [round(float(x), 4) for x in self.sim.base_position()],
                "sim_time": round(self.sim.time, 4), "commands_received": self.dds.received,
                "commands_bad_crc": self.dds.bad_crc, "states_sent": self.dds.sent, "loop": self.loop.summary(),
                "real_time_share": round(1 - self.loop.overruns / max(1, self.loop.ticks), 4)}

    def write_report(self, path: str) -> None:
        with open(path, "w") as f:
            json.dump(self.report(), f, indent=1)
