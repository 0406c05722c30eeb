"""MuJoCo's passive viewer, closed so that the process can exit cleanly (pchc-play, the sim-to-sim bridge).

``Handle.close()`` only asks the viewer's daemon thread to stop; a process that exits before that thread's render
loop has finished lets GLFW terminate under a frame still being swapped (GLXBadDrawable and a segfault at exit under
Xvfb, seen in CI). Closing here waits for the thread. Neither torch nor the envs are imported here: the bridge runs
without them."""

from __future__ import annotations

import contextlib
import threading


@contextlib.contextmanager
def passive_viewer(model, data, **kwargs):
    """``mujoco.viewer.launch_passive(model, data, **kwargs)``'s handle; on leaving, closed and its thread joined."""
    import mujoco.viewer  # GLFW's window code, loaded only where a window opens

    before = set(threading.enumerate())
    handle = mujoco.viewer.launch_passive(model, data, **kwargs)
    viewer_threads = [thread for thread in threading.enumerate() if thread not in before]
    try:
        yield handle
    finally:
        handle.close()
        for thread in viewer_threads:
            thread.join(timeout=10.0)
