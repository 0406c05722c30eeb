"""Pictures of a G1Env: the full visual model (meshes) posed from the physics state, pushes drawn as arrows.

The physics model has no meshes (DESIGN.md); ``build_g1_model(visual=True)`` has the same joints and qpos layout,
so a picture of env i is: its physics qpos copied into the visual model's MjData, a forward pass, a render.
"""

from __future__ import annotations

import os

import mujoco
import numpy as np

from pchc_rsl.robots.g1.model import build_g1_model

PUSH_RGBA = np.array([0.95, 0.2, 0.1, 1.0], dtype=np.float32)
CAMERA = {"distance": 3.0, "azimuth": 150.0, "elevation": -15.0, "height": 0.55}
"""A free camera that follows the pelvis at this height, looking at the robot's front left."""


class RenderingUnavailable(RuntimeError):
    """No OpenGL context for offscreen rendering; the message says which MUJOCO_GL values to try."""


def rendering_help(error: Exception | str) -> str:
    value = os.environ.get("MUJOCO_GL", "")
    return (f"offscreen rendering is unavailable with MUJOCO_GL={value or '(unset: glfw, needs a display)'} "
            f"({error}). Try MUJOCO_GL=egl (headless, GPU or Mesa's EGL: apt-get install libegl1 libgl1-mesa-dri), "
            "MUJOCO_GL=osmesa (software: apt-get install libosmesa6), or MUJOCO_GL=glfw under a display "
            "(e.g. xvfb-run -a). MUJOCO_GL must be set before Python starts.")


def visual_model(env, width: int = 640, height: int = 480) -> mujoco.MjModel:
    """The task's G1 with its meshes, checked to share the physics model's qpos layout."""
    model = build_g1_model(env.cfg.joints, env.cfg.timestep, visual=True, held_joints=tuple(env.cfg.held_joints))
    physics = env.model
    same = model.nq == physics.nq and all(
        model.joint(i).name == physics.joint(i).name for i in range(physics.njnt))
    if not same:
        raise RuntimeError("The visual G1 model does not share the physics model's joints; cannot render this env.")
    # multisampling costs 2.5x in software rendering (Mesa's llvmpipe) for little visible gain at video sizes
    model.vis.quality.offsamples = 0
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    return model


def follow_camera(base_pos: np.ndarray, camera: mujoco.MjvCamera | None = None) -> mujoco.MjvCamera:
    """A free camera (new, or the given one) looking at the robot from CAMERA's distance and angles."""
    camera = camera or mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.lookat[:] = (base_pos[0], base_pos[1], CAMERA["height"])
    camera.distance, camera.azimuth, camera.elevation = CAMERA["distance"], CAMERA["azimuth"], CAMERA["elevation"]
    return camera


def add_push_arrow(scene: mujoco.MjvScene, base_pos: np.ndarray, direction: np.ndarray) -> None:
    """An arrow that hits the pelvis along the horizontal push direction d [2] (drawn while the window is open)."""
    if scene.ngeom >= scene.maxgeom:
        return
    d = np.array([direction[0], direction[1], 0.0])
    end = np.asarray(base_pos, dtype=float) - 0.15 * d
    start = end - 0.8 * d
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_ARROW, np.zeros(3), np.zeros(3), np.eye(3).ravel(), PUSH_RGBA)
    mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_ARROW, 0.04, start, end)
    geom.emission = 0.7  # bright whichever way it points relative to the lights
    scene.ngeom += 1


class G1Renderer:
    """Offscreen pictures [height, width, 3] of single envs of a G1Env."""

    def __init__(self, env, width: int, height: int) -> None:
        self.model = visual_model(env, width, height)
        self.data = mujoco.MjData(self.model)
        try:
            self.renderer = mujoco.Renderer(self.model, height=height, width=width)
        except Exception as error:  # noqa: BLE001 - each GL backend fails in its own way
            raise RenderingUnavailable(rendering_help(error)) from error
        self.camera = mujoco.MjvCamera()

    def render(self, env, i: int) -> np.ndarray:
        """Env i as it is now, with an arrow while it is inside the window after a push."""
        self.data.qpos[:] = env.physics.qpos[i].cpu().numpy()
        mujoco.mj_forward(self.model, self.data)
        base = env.physics.qpos[i, :3].cpu().numpy()
        self.renderer.update_scene(self.data, follow_camera(base, self.camera))
        if bool(env.pushes.active[i]):
            add_push_arrow(self.renderer.scene, base, env.pushes.direction[i].numpy())
        return self.renderer.render().copy()

    def close(self) -> None:
        self.renderer.close()
