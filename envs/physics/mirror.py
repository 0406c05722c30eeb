"""One env's physics calls made on other physics too: the same inputs for two backends (or two solver settings).

An env draws its randomness (start states, commands, pushes, action delays) on its own device; two envs on two
devices draw different numbers from one seed. Mirroring the calls of one env's physics instead feeds every mirror
the same resets, controls, body forces and state writes (a push's velocity kick), so that what differs between
them is the physics alone (``tools/gpu/warp_parity.py``, ``tools/gpu/solver_iterations.py``).
"""

from __future__ import annotations

import copy
from collections.abc import Callable

import mujoco
import torch


def edited_copies(models: list[mujoco.MjModel], edit: Callable[[mujoco.MjModel], None]) -> list[mujoco.MjModel]:
    """A copy of each distinct model with ``edit`` applied, in the same places of the list (env i keeps sharing
    variant i mod V, as WarpMuJoCo requires)."""
    copies: dict[int, mujoco.MjModel] = {}
    for model in models:
        if id(model) not in copies:
            copies[id(model)] = copy.copy(model)
            edit(copies[id(model)])
    return [copies[id(model)] for model in models]


class MirroredPhysics:
    """Wraps an env's physics in place: each call (``step``, ``set_qpos_qvel``, ``sanitize``) is made on it and on
    every mirror, and what the env wrote into qpos, qvel or the body forces since the last call is written into the
    mirrors too. A mirror with a ``start_offset`` ([1, nq]) starts every reset that far from the env's state.
    After every step ``stepped`` holds each mirror's (qpos, qvel) as the step left them and ``reference`` the env's
    physics' (before the env resets any of its envs). ``resync=True`` then copies the env's state into the mirrors:
    each step starts from the same state, and the differences are those of one step."""

    def __init__(self, physics, mirrors: list, resync: bool = False) -> None:
        self.physics, self.mirrors, self.resync = physics, mirrors, resync
        self.stepped: list[tuple[torch.Tensor, torch.Tensor]] = []
        self.reference: tuple[torch.Tensor, torch.Tensor] | None = None
        self._remember()
        self._step, self._reset, self._sanitize = physics.step, physics.set_qpos_qvel, physics.sanitize
        physics.step, physics.set_qpos_qvel, physics.sanitize = self.step, self.set_qpos_qvel, self.sanitize

    def _remember(self) -> None:
        self._qpos, self._qvel = self.physics.qpos.clone(), self.physics.qvel.clone()

    def _carry_writes(self) -> None:
        p = self.physics
        dq, dv = p.qpos - self._qpos, p.qvel - self._qvel
        for mirror in self.mirrors:
            mirror.qpos += dq.to(mirror.qpos)
            mirror.qvel += dv.to(mirror.qvel)
            if p.body_forces is not None:
                mirror.body_forces.copy_(p.body_forces.to(mirror.body_forces))

    def step(self, ctrl) -> None:
        self._carry_writes()
        self._step(ctrl)
        self.reference = (self.physics.qpos.clone(), self.physics.qvel.clone())
        self.stepped = []
        for mirror in self.mirrors:
            mirror.step(torch.as_tensor(ctrl).to(mirror.qpos))
            self.stepped.append((mirror.qpos.clone(), mirror.qvel.clone()))
            if self.resync:
                mirror.qpos.copy_(self.physics.qpos.to(mirror.qpos))
                mirror.qvel.copy_(self.physics.qvel.to(mirror.qvel))
        self._remember()

    def set_qpos_qvel(self, env_ids, qpos, qvel) -> None:
        self._carry_writes()
        self._reset(env_ids, qpos, qvel)
        for mirror in self.mirrors:
            offset = getattr(mirror, "start_offset", None)
            start = qpos + offset.to(qpos) if offset is not None else qpos
            mirror.set_qpos_qvel(torch.as_tensor(env_ids).to(mirror.device), start.to(mirror.device),
                                 qvel.to(mirror.device))
        self._remember()

    def sanitize(self, envs) -> None:
        self._sanitize(envs)
        for mirror in self.mirrors:
            mirror.sanitize(torch.as_tensor(envs).to(mirror.device))
        self._remember()
