"""pchc-deploy's browser console: the web viewer's lambda controls, one slider per command component the policy
was trained with (forward, lateral, yaw rate, each over its trained range) and the safety buttons, for steering the
robot (or the sim bridge) from a laptop. It only queues input; the deploy loop applies it, as it applies keys and
the remote."""

from __future__ import annotations

import queue

import numpy as np

from pchc_rsl.deploy.live_controls import COMMAND_COMPONENTS, COMMAND_WORDS
from pchc_rsl.viewers.web_page import (DEFAULT_HOST, add_preference_controls, check_port, preference_markdown,
                                       require_viser)


class DeployConsole:
    def __init__(self, objective_names: list[str], preference, command_ranges: dict | None, command=(0.0, 0.0, 0.0),
                 host: str = DEFAULT_HOST, port: int = 8080) -> None:
        """``command_ranges``: component -> (low, high) as the policy file states them; None: no command."""
        viser, _ = require_viser()
        check_port(host, port)
        self.names = objective_names
        self.events: queue.Queue = queue.Queue()
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.url = f"http://{host}:{self.server.get_port()}"
        gui = self.server.gui
        self.status = gui.add_markdown("waiting for the robot's state")
        self.buttons = {}
        with gui.add_folder("Robot"):
            for label, key in (("Start: ramp to the default pose", "s"), ("Policy", "p"), ("Damping", " ")):
                self.buttons[key] = gui.add_button(label)
                self.buttons[key].on_click(lambda _, key=key: self.events.put(key))
        with gui.add_folder("Preference lambda"):
            self.preference_sliders, self.preference_text = add_preference_controls(
                gui, objective_names, preference, lambda lam: self.events.put(("preference", lam)))
        self.command_sliders: dict[str, object] = {}
        trained = {k: r for k, r in (command_ranges or {}).items() if r[1] > r[0]}
        if trained:
            with gui.add_folder("Command"):
                for i, key in enumerate(COMMAND_COMPONENTS):
                    if key in trained:
                        low, high = trained[key]
                        name, unit, *_ = COMMAND_WORDS[key]
                        slider = gui.add_slider(f"{name} ({unit})", low, high, 0.05, float(command[i]))
                        slider.on_update(lambda _: self.events.put(("command", self.command_value())))
                        self.command_sliders[key] = slider

    def command_value(self) -> list[float]:
        """(forward, lateral, yaw rate) from the sliders; 0 for a component the policy has no slider for."""
        return [float(self.command_sliders[k].value) if k in self.command_sliders else 0.0 for k in COMMAND_COMPONENTS]

    def pending(self) -> list:
        """Keys ('s', 'p', ' ') and (name, value) settings queued since the last call."""
        out = []
        while not self.events.empty():
            out.append(self.events.get_nowait())
        return out

    def show(self, mode: str, reason: str, preference, command: np.ndarray | None) -> None:
        self.status.content = f"mode: **{mode}**" + (f" ({reason})" if reason else "")
        text = preference_markdown(self.names, preference)
        if command is not None:
            text += ", command " + ", ".join(f"{COMMAND_WORDS[k][0]} **{command[i]:+.2f}**"
                                             for i, k in enumerate(COMMAND_COMPONENTS) if k in self.command_sliders)
        self.preference_text.content = text

    def close(self) -> None:
        self.server.stop()
