"""Whether a window can open here, and the OpenGL backend MuJoCo renders offscreen with when none can.

MuJoCo reads MUJOCO_GL once, when it is first imported: its default (GLFW) needs a display, so a command that may
render without one (pchc-eval --video, pchc-play --video) chooses EGL before anything imports mujoco.
"""

from __future__ import annotations

import os
import sys


def has_display() -> bool:
    """Whether a window can open here (macOS, Windows, or an X11 / Wayland display)."""
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def prefer_headless_gl() -> None:
    """MUJOCO_GL=egl where no window can open and MUJOCO_GL is not set; call it before mujoco is imported."""
    if not has_display():
        os.environ.setdefault("MUJOCO_GL", "egl")
