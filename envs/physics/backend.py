"""Choosing the physics backend of a G1 env: C MuJoCo on the CPU (default) or MuJoCo Warp on a device."""

from __future__ import annotations

import mujoco

from pchc_rsl.envs.physics.batched_mujoco import BatchedMuJoCo
from pchc_rsl.envs.physics.warp_settings import WarpSettings

BACKENDS = ("mujoco", "warp")


def physics_device(backend: str, device: str) -> str:
    """Where the env's tensors live: the CPU for C MuJoCo, the requested device for Warp."""
    if backend not in BACKENDS:
        raise ValueError(f"physics '{backend}' is not a backend; use one of {', '.join(BACKENDS)}.")
    return "cpu" if backend == "mujoco" else str(device)


def make_physics(backend: str, models: list[mujoco.MjModel], num_envs: int, substeps: int, num_threads: int,
                 device: str, with_body_forces: bool, warp: WarpSettings | None = None):
    """BatchedMuJoCo (threads: native threads stepping the batch) or WarpMuJoCo on ``device`` with ``warp``'s
    buffers and solver settings."""
    if backend == "warp":
        from pchc_rsl.envs.physics.warp_mujoco import WarpMuJoCo  # MuJoCo Warp: the optional warp extra

        return WarpMuJoCo(models, num_envs, substeps, device, with_body_forces=with_body_forces, settings=warp)
    return BatchedMuJoCo(models, num_envs, substeps, num_threads, with_body_forces=with_body_forces)
