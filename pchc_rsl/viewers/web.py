"""Watch and steer a policy from a browser: the full visual G1 (viser, with mjviser converting the MuJoCo scene)
posed from the physics state in real time, lambda on a slider, the command, pushes, reset, pause, step and speed,
and live panels of each objective's reward and the task's metrics. Works over an SSH tunnel from a headless server,
which MuJoCo's native viewer does not.

GUI callbacks run on viser's thread; they only queue actions, which the simulation loop applies between policy
steps (as the native viewer's keys do).
"""

from __future__ import annotations

import collections
import math
import random
import threading
import time

import mujoco
import numpy as np
import torch

from pchc_rsl.envs.g1.render import visual_model
from pchc_rsl.envs.g1.robot_state import yaw_of
from pchc_rsl.envs.toy_render import ToyPlot
from pchc_rsl.export.metadata import COMMAND_COMPONENTS
from pchc_rsl.viewers.overlay import live_metrics
from pchc_rsl.viewers.steering import COMMAND_LABELS, set_command, trained_ranges
from pchc_rsl.viewers.web_page import (DEFAULT_HOST, DEFAULT_PORT, add_preference_controls, check_port,
                                       preference_markdown, require_viser)

HISTORY_S = 5.0
"""The reward panel shows this many seconds."""
PANEL_EVERY_S = 0.25
"""Refresh the panels this often."""
SCENE_EVERY_S = 1 / 30
"""Pose the scene at most 30 times a second: every update makes the browser render a frame, which is what costs
on a machine without a GPU (software WebGL)."""
PUSH_DIRECTIONS = {"random": None, "forward": 0.0, "left": math.pi / 2, "backward": math.pi, "right": -math.pi / 2}
"""Push directions relative to the robot's heading (rad); None: a random world direction."""


def add_command_controls(gui, cfg, initial, on_change) -> dict:
    """One slider per command component the task trains (forward, lateral, yaw rate), over its trained range;
    ``on_change(component, value)`` runs on viser's thread. Returns the sliders by component."""
    sliders = {}
    for key, (low, high) in trained_ranges(cfg).items():
        k = COMMAND_COMPONENTS.index(key)
        slider = gui.add_slider(COMMAND_LABELS[key], low, high, 0.05, min(high, max(low, float(initial[k]))))
        slider.on_update(lambda _, k=k, slider=slider: on_change(k, slider.value))
        sliders[key] = slider
    return sliders


class WebViewer:
    """One env (env 0) of a checkpoint's evaluation env, its policy, and the page that shows and steers it."""

    def __init__(self, env, policy, preference, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT,
                 speed: float = 1.0, pushes: dict | None = None) -> None:
        """``pushes``: the task's push presets by name (pchc_rsl.evaluation.presets.PushPreset), offered as the
        push's strength: a velocity kick, or a force drawn from the preset's range on one of its bodies."""
        viser, ViserMujocoScene = require_viser()
        check_port(host, port)
        self.env, self.policy = env, policy
        self.is_g1 = hasattr(env, "physics")
        self.dt = float(env.dt) if self.is_g1 else 0.1  # the toy has no physical time: 10 steps a second
        self.speed, self.paused, self.steps_requested = speed, False, 0
        self.pushes = pushes or {}
        self.pending: collections.deque = collections.deque()
        self.lock = threading.Lock()
        self.falls = self.steps = self.pushes_done = 0
        self.history = collections.deque(maxlen=max(2, round(HISTORY_S / self.dt)))
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.url = f"http://{host}:{self.server.get_port()}"
        env.set_preference(torch.tensor(preference, dtype=torch.float32))
        env.reset()
        self.obs = env.get_observations()
        if self.is_g1:
            self.plot = None
            self._build_gui()  # the controls go out before the meshes, which take long to reach a browser
            self.model = visual_model(env)
            self.data = mujoco.MjData(self.model)
            self.scene = ViserMujocoScene(self.server, self.model, num_envs=1)  # follows the pelvis: it stays at 0
            self.server.initial_camera.position = (2.2, -2.2, 0.5)
            self.server.initial_camera.look_at = (0.0, 0.0, -0.25)
        else:
            self.scene, self.plot = None, ToyPlot(env, 480, 360)
            self.plot.record()
            self._build_gui()
        self._show()

    # ------------------------------------------------------------------ the page
    def _build_gui(self) -> None:
        gui, env = self.server.gui, self.env
        names = list(env.cfg.objective_names)
        if self.plot is not None:
            self.picture = gui.add_image(self.plot.render(env, 0), label="trajectory")
        with gui.add_folder("Preference lambda"):
            self.preference_sliders, self.preference_text = add_preference_controls(
                gui, names, env.preference[0].tolist(), lambda lam: self.queue("preference", lam))
        self.command_sliders = {}
        if trained_ranges(env.cfg):
            with gui.add_folder("Command"):
                self.command_sliders = add_command_controls(gui, env.cfg, env.commands[0].tolist(),
                                                            lambda k, v: self.queue("command", (k, v)))
        if self.is_g1:
            with gui.add_folder("Push"):
                strength = gui.add_dropdown("strength", tuple(self.pushes) or ("preset",))
                direction = gui.add_dropdown("direction", tuple(PUSH_DIRECTIONS))
                self.push_button = gui.add_button("Push")
                self.push_button.on_click(lambda _: self.queue("push", (strength.value, direction.value)))
        with gui.add_folder("Run"):
            gui.add_button("Reset").on_click(lambda _: self.queue("reset"))
            pause = gui.add_checkbox("Pause", False)
            pause.on_update(lambda _: self.queue("pause", pause.value))
            gui.add_button("Step").on_click(lambda _: self.queue("step"))
            speed = gui.add_slider("speed (x real time)", 0.1, max(2.0, self.speed), 0.1, self.speed)
            speed.on_update(lambda _: self.queue("speed", speed.value))
        colors = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728"]  # matplotlib's first four, as in the Pareto plots
        series = [{"label": "t (s)"}, {"label": "task", "stroke": "gray"}]
        series += [{"label": n, "stroke": colors[i % 4]} for i, n in enumerate(names)]
        empty = tuple(np.zeros(2) for _ in series)
        self.reward_plot = gui.add_uplot(empty, tuple(series), title="rewards per step", aspect=1.6,
                                         scales={"x": {"time": False}},  # seconds since the start, not dates
                                         axes=({"label": "t (s)"}, {}))
        self.metrics_text = gui.add_markdown("")

    # ------------------------------------------------------------------ controls (any thread)
    def queue(self, action: str, value=None) -> None:
        with self.lock:
            self.pending.append((action, value))

    def apply_pending(self) -> bool:
        """Apply the queued actions to the env; True if the policy needs fresh observations."""
        changed = False
        with self.lock:
            actions = list(self.pending)
            self.pending.clear()
        for action, value in actions:
            env = self.env
            if action == "preference":
                env.set_preference(torch.tensor(value, dtype=torch.float32))
                changed = True
            elif action == "command":  # (component, value)
                changed = set_command(env, *value) or changed
            elif action == "push":
                self._push(*value)
            elif action == "reset":
                env.reset()
                self.history.clear()
                changed = True
            elif action == "pause":
                self.paused = bool(value)
            elif action == "step":
                self.steps_requested += 1
            elif action == "speed":
                self.speed = float(value)
        if changed:
            self.obs = self.env.get_observations()
        return changed

    def _push(self, strength: str, direction: str) -> None:
        preset = self.pushes.get(strength)
        offset = PUSH_DIRECTIONS[direction]
        angle = None if offset is None else float(yaw_of(self.env.robot.base_quat[:1])[0]) + offset
        if preset is not None and preset.force is not None:
            body = self.env.model.body(random.choice(preset.bodies)).id
            self.env.pushes.request(0, angle=angle, force=random.uniform(*preset.force), duration_s=preset.duration_s,
                                    body_id=body)
        else:
            self.env.pushes.request(0, None if preset is None else preset.speed, angle)
        self.pushes_done += 1

    # ------------------------------------------------------------------ simulation
    def step(self) -> None:
        with torch.inference_mode():
            self.obs, _, _, extras = self.env.step(self.policy(self.obs))
        self.steps += 1
        finished = extras.get("episode_metrics")
        if finished is not None and len(finished["env_ids"]):
            self.falls += int(finished["fell"].sum())
        groups = extras.get("reward_groups")
        if groups is None and hasattr(self.env, "objective_rewards"):  # the toy: its objectives are the rewards
            groups = torch.cat([torch.zeros(1, 1), self.env.objective_rewards()[:1]], dim=-1)
        if groups is not None:
            self.history.append((self.steps * self.dt, *groups[0].tolist()))
        if self.plot is not None:
            self.plot.record()

    def _show(self) -> None:
        """Pose the scene from the physics state (or redraw the toy's plot)."""
        if self.scene is not None:
            self.data.qpos[:] = self.env.physics.qpos[0].cpu().numpy()
            mujoco.mj_forward(self.model, self.data)
            self.scene.update_from_mjdata(self.data)

    def _panels(self) -> None:
        self.preference_text.content = preference_markdown(self.env.cfg.objective_names,
                                                           self.env.preference[0].tolist())
        if self.history:
            columns = np.array(self.history).T
            self.reward_plot.data = tuple(columns)
        rows = live_metrics(self.env, 0, self.falls)
        if self.is_g1:
            metrics = {k: float(v[0]) for k, v in self.env.episode_metrics(torch.tensor([0])).items()}
            extra = {"forward_step": ("forward step", "m"), "cadence": ("cadence", "/s per foot"),
                     "air_time": ("air time", "s"), "forward_speed": ("forward speed", "m/s"),
                     "energy_overall": ("energy", "J/s")}
            shown = {name for name, _ in rows}
            rows += [(label, f"{metrics[k]:.2f} {unit}") for k, (label, unit) in extra.items()
                     if k in metrics and not math.isnan(metrics[k]) and label not in shown]
            rows.append(("pushes", str(self.pushes_done)))
        rows.append(("time", f"{self.steps * self.dt:.1f} s" + (" (paused)" if self.paused else "")))
        self.metrics_text.content = "\n".join(f"- {name}: **{value}**" for name, value in rows)
        if self.plot is not None:
            self.picture.image = self.plot.render(self.env, 0)

    def run(self, seconds: float | None = None, stop: threading.Event | None = None) -> None:
        """Step in real time (times the speed slider) until ``seconds`` of simulation or ``stop``; Ctrl-C ends it."""
        stop = stop or threading.Event()
        last_panel = last_scene = 0.0
        try:
            while not stop.is_set() and (seconds is None or self.steps * self.dt < seconds):
                start = time.perf_counter()
                self.apply_pending()
                if not self.paused or self.steps_requested:
                    self.steps_requested = max(0, self.steps_requested - 1)
                    self.step()
                    if start - last_scene >= SCENE_EVERY_S or self.paused:
                        self._show()
                        last_scene = start
                if start - last_panel >= PANEL_EVERY_S:
                    self._panels()
                    last_panel = start
                period = self.dt / max(self.speed, 1e-3) if not self.paused else 0.02
                time.sleep(max(0.0, period - (time.perf_counter() - start)))
        except KeyboardInterrupt:
            pass

    def close(self) -> None:
        self.server.stop()
