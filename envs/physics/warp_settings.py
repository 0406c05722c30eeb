"""MuJoCo Warp's fixed per-world sizes and solver settings, chosen per task (``env.warp.*``).

C MuJoCo grows its buffers as a step needs; Warp allocates them once, for every world, and drops what does not fit
(contacts, constraint rows): a robot lying on the floor touches it with most of its body and needs about twice the
rows of a standing one (about 64 against 32). The sizes below come from the peaks measured on Warp over prone, lying
and fallen G1s of both tasks (``tools/gpu/warp_buffers.py``; figures and memory in docs/gpu.md), with a margin of 2.5;
fall recovery, whose robots spend their episodes on the floor, sets more (configs/g1_fall_recovery.py).
"""

from __future__ import annotations

from dataclasses import dataclass

from pchc_rsl.utils.physics_overflow import PhysicsOverflow  # noqa: F401 - what warp_mujoco.py raises


@dataclass
class WarpSettings:
    """Buffers and solver of ``--physics warp`` (C MuJoCo ignores them)."""

    constraints_per_env: int = 160
    """Constraint rows of one world (Warp's njmax): 4 per contact (pyramidal cones of condim 3), joint limits and
    friction loss. Measured peak 64 (128 walking robots lying or falling, every substep); a prone robot at rest
    needs 72 on C MuJoCo. 4096 worlds: 395 MB with 32 contacts (298 MB at 64 rows and 16 contacts)."""
    contacts_per_env: int = 32
    """Contacts per world on average (Warp's nconmax: one pool of contacts_per_env * num_envs for all worlds, so one
    world may hold more). Measured peak 16 in one world, 10 per world over all worlds at once."""
    solver_iterations: int = 10
    """Newton iterations per step (mjlab's G1 value): inside a captured step the slowest world sets the cost of the
    whole batch, so the step stops here whether or not it converged (docs/gpu.md: 10 against 100)."""
    linesearch_iterations: int = 20

    def check(self) -> None:
        """ValueError naming the first setting that is not a whole number >= 1 (checked when the physics is built:
        overrides arrive after construction)."""
        for name in ("constraints_per_env", "contacts_per_env", "solver_iterations", "linesearch_iterations"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ValueError(f"env.warp.{name} must be a whole number >= 1, got {value!r}.")
