"""MuJoCo's passive viewer on a running policy, with keys that move lambda, push and reset (pchc-play)."""

from __future__ import annotations

import time
from collections import deque

import mujoco
import torch

from pchc_rsl.envs.g1.render import add_push_arrow, visual_model
from pchc_rsl.viewers.overlay import live_metrics, preference_row
from pchc_rsl.viewers.passive import passive_viewer
from pchc_rsl.viewers.steering import set_command, trained_ranges

LAMBDA_STEP = 0.1
"""How far one key press moves lambda along the simplex."""


RIGHT, LEFT, SPACE, BACKSPACE = 262, 263, 32, 259
UP, DOWN, PAGE_UP, PAGE_DOWN, HOME, END = 265, 264, 266, 267, 268, 269
"""GLFW key codes of the keys the passive viewer leaves to its user (its letters toggle rendering flags)."""
KEYS = {RIGHT: "right", LEFT: "left", SPACE: "push", BACKSPACE: "reset"}
COMMAND_KEYS = {UP: (0, 0.1), DOWN: (0, -0.1), PAGE_UP: (1, 0.1), PAGE_DOWN: (1, -0.1), HOME: (2, 0.1),
                END: (2, -0.1)}
"""key -> (command component, change): forward m/s, lateral m/s (Page Up: left), yaw rate rad/s (Home: left)."""


def key_help(objective_names: list[str], steered: tuple[str, ...] = ()) -> str:
    """``steered``: the command components the policy takes (lin_vel_x, lin_vel_y, ang_vel_z)."""
    first, second = objective_names
    lines = [f"Left: more {first}", f"Right: more {second}", "Space: push", "Backspace: reset"]
    words = {"lin_vel_x": "Up/Down: forward +/- 0.1 m/s", "lin_vel_y": "PgUp/PgDn: left/right 0.1 m/s",
             "ang_vel_z": "Home/End: turn left/right 0.1 rad/s"}
    return "\n".join(lines + [words[k] for k in steered])


class LiveControls:
    """The viewer's keys: queued from the viewer's thread, applied between policy steps on env 0."""

    def __init__(self, env) -> None:
        self.env, self.pending = env, deque()

    def on_key(self, keycode: int) -> None:
        if keycode in KEYS:
            self.pending.append(KEYS[keycode])
        elif keycode in COMMAND_KEYS:
            self.pending.append(COMMAND_KEYS[keycode])

    def apply(self) -> bool:
        """Apply the queued keys; True if any did (the policy then needs fresh observations)."""
        env, changed = self.env, bool(self.pending)
        while self.pending:
            action = self.pending.popleft()
            if action in ("left", "right") and env.num_objectives == 2:
                t = float(env.preference[0, 1]) + (LAMBDA_STEP if action == "right" else -LAMBDA_STEP)
                t = min(1.0, max(0.0, round(t / LAMBDA_STEP) * LAMBDA_STEP))
                env.set_preference(torch.tensor([1.0 - t, t]))
            elif action == "push":
                env.pushes.countdown[:] = 1  # the next step pushes, at the preset's strength, in a random direction
            elif action == "reset":
                env.reset()
            elif isinstance(action, tuple):  # (command component, change)
                component, delta = action
                set_command(env, component, float(env.commands[0, component]) + delta)
        return changed


def run_viewer(env, policy, preference, seconds: float | None) -> int:
    """MuJoCo's passive viewer on env 0 in real time until closed (or ``seconds`` of simulation); returns steps."""
    model = visual_model(env)
    data = mujoco.MjData(model)
    controls = LiveControls(env)
    steps, falls = 0, 0
    with passive_viewer(model, data, key_callback=controls.on_key, show_left_ui=False,
                        show_right_ui=False) as handle:
        with handle.lock():
            handle.cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
            handle.cam.trackbodyid = model.body("pelvis").id
            handle.cam.distance, handle.cam.azimuth, handle.cam.elevation = 3.0, 150.0, -15.0
        with torch.inference_mode():
            env.set_preference(torch.tensor(preference, dtype=torch.float32))
            env.reset()
            obs = env.get_observations()
            while handle.is_running() and (seconds is None or steps * env.dt < seconds):
                start = time.perf_counter()
                if controls.apply():
                    obs = env.get_observations()
                obs, _, _, extras = env.step(policy(obs))
                falls += int(extras["episode_metrics"]["fell"].sum())
                steps += 1
                with handle.lock():
                    data.qpos[:] = env.physics.qpos[0].cpu().numpy()
                    mujoco.mj_forward(model, data)
                    handle.user_scn.ngeom = 0
                    if bool(env.pushes.active[0]):
                        add_push_arrow(handle.user_scn, env.physics.qpos[0, :3].cpu().numpy(),
                                       env.pushes.direction[0].cpu().numpy())
                rows = [preference_row(env, 0)] + live_metrics(env, 0, falls)
                handle.set_texts([
                    (None, mujoco.mjtGridPos.mjGRID_TOPLEFT, "\n".join(n for n, _ in rows),
                     "\n".join(v for _, v in rows)),
                    (None, mujoco.mjtGridPos.mjGRID_BOTTOMLEFT,
                     key_help(env.cfg.objective_names, tuple(trained_ranges(env.cfg))), ""),
                ])
                handle.sync()
                time.sleep(max(0.0, env.dt - (time.perf_counter() - start)))
    return steps
