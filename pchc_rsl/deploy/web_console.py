"""pchc-deploy's browser console: the web viewer's lambda and command controls plus the safety buttons, for moving
lambda live on the robot (or the sim bridge) from a laptop. It only queues input; the deploy loop applies it, as it
applies keys and the remote's buttons."""

from __future__ import annotations

import queue

from pchc_rsl.web_viewer import (DEFAULT_HOST, add_command_control, add_preference_controls, check_port,
                                 preference_markdown, require_viser)


class DeployConsole:
    def __init__(self, objective_names: list[str], preference, command: float | None, host: str = DEFAULT_HOST,
                 port: int = 8080) -> None:
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
            for label, key in (("Start: ramp to the default pose", "s"), ("Policy", "p"), ("Damping", "d")):
                self.buttons[key] = gui.add_button(label)
                self.buttons[key].on_click(lambda _, key=key: self.events.put(key))
        with gui.add_folder("Preference lambda"):
            self.preference_sliders, self.preference_text = add_preference_controls(
                gui, objective_names, preference, lambda lam: self.events.put(("preference", lam)))
        self.command_slider = None
        if command is not None:
            with gui.add_folder("Command"):
                self.command_slider = add_command_control(gui, command, lambda v: self.events.put(("command", v)))

    def pending(self) -> list:
        """Keys ('s', 'p', 'd') and (name, value) settings queued since the last call."""
        out = []
        while not self.events.empty():
            out.append(self.events.get_nowait())
        return out

    def show(self, mode: str, reason: str, preference, command: float | None) -> None:
        self.status.content = f"mode: **{mode}**" + (f" ({reason})" if reason else "")
        text = preference_markdown(self.names, preference)
        self.preference_text.content = text + (f", command **{command:+.2f} m/s**" if command is not None else "")

    def close(self) -> None:
        self.server.stop()
