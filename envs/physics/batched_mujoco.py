"""Batched C MuJoCo: N copies of one model stepped together on native threads (mujoco.rollout, GIL released).

The interface an environment uses, shared with the MuJoCo Warp backend (``warp_mujoco.py``): torch views of the
latest joint state, of every substep's sensors and joint velocities, and of the external body forces; ``step`` with
a held control, ``set_qpos_qvel`` to reset some envs, ``sanitize`` to clear diverged ones. Here the views share
memory with the numpy buffers that mujoco.rollout fills (float64, on the CPU).
"""

from __future__ import annotations

import mujoco
import numpy as np
import torch
from mujoco import rollout

STATE_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS


class BatchedMuJoCo:
    """N environments of one MjModel (or N same-sized models for per-env physical randomisation)."""

    device = "cpu"

    def __init__(self, models: mujoco.MjModel | list[mujoco.MjModel], num_envs: int, substeps: int,
                 num_threads: int = 1, with_body_forces: bool = False) -> None:
        self.models = models if isinstance(models, list) else [models] * num_envs
        if len(self.models) != num_envs:
            raise ValueError(f"Got {len(self.models)} models for {num_envs} envs.")
        self.model = self.models[0]
        self.num_envs, self.substeps = num_envs, substeps
        self.datas = [mujoco.MjData(self.model) for _ in range(num_threads)]
        self.runner = rollout.Rollout(nthread=num_threads)
        m = self.model
        self.nstate = mujoco.mj_stateSize(m, STATE_SPEC)
        self.qpos_slice = slice(1, 1 + m.nq)  # state layout: time, qpos, qvel, act, ...
        self.qvel_slice = slice(1 + m.nq, 1 + m.nq + m.nv)
        self.state = np.zeros((num_envs, self.nstate))
        """The full physics state of every env (numpy, C backend only: tools record and replay it)."""
        data = mujoco.MjData(m)
        mujoco.mj_getState(m, data, self.state[0], STATE_SPEC)
        self.state[:] = self.state[0]
        self.state_records = np.zeros((num_envs, substeps, self.nstate))
        self.sensor_records = np.zeros((num_envs, substeps, m.nsensordata))
        # the control vector: ctrl, then (optionally) xfrc_applied, the Cartesian force/torque on every body
        self.control_spec = mujoco.mjtState.mjSTATE_CTRL
        width = m.nu
        if with_body_forces:
            self.control_spec |= mujoco.mjtState.mjSTATE_XFRC_APPLIED
            width += 6 * m.nbody
        self.control = np.zeros((num_envs, substeps, width))
        self._body_forces = np.zeros((num_envs, m.nbody, 6)) if with_body_forces else None

        state = torch.from_numpy(self.state)
        self.qpos, self.qvel = state[:, self.qpos_slice], state[:, self.qvel_slice]
        """[N, nq], [N, nv] views of the latest state (writable: a push adds to qvel)."""
        self.substep_sensors = torch.from_numpy(self.sensor_records)
        """[N, K, nsensordata]: the sensors of each of the last step's K substeps."""
        self.substep_qvel = torch.from_numpy(self.state_records)[:, :, self.qvel_slice]
        """[N, K, nv]: the joint velocities after each of the last step's substeps."""
        self.body_forces = None if self._body_forces is None else torch.from_numpy(self._body_forces)
        """[N, nbody, 6] external force and torque on each body, held through a step (None unless enabled)."""
        self.diverged = torch.zeros(num_envs, dtype=torch.bool)
        """Envs whose physics MuJoCo had to reset during the last step."""

    def step(self, ctrl: torch.Tensor | np.ndarray) -> None:
        """Advance every env ``substeps`` physics steps holding ``ctrl`` [N, nu], or with one control per substep
        [N, K, nu] (an action delay switches the target part-way through the step), and ``body_forces``."""
        nu = self.model.nu
        expected_time = self.state[:, 0] + self.substeps * self.model.opt.timestep
        ctrl = np.asarray(ctrl)
        self.control[:, :, :nu] = ctrl if ctrl.ndim == 3 else ctrl[:, None, :]
        if self._body_forces is not None:
            self.control[:, :, nu:] = self._body_forces.reshape(self.num_envs, 1, -1)
        self.runner.rollout(
            self.models, self.datas, self.state, self.control, control_spec=self.control_spec, nstep=self.substeps,
            state=self.state_records, sensordata=self.sensor_records, skip_checks=True,
        )
        self.state[:] = self.state_records[:, -1]
        # MuJoCo resets an env's data by itself when its accelerations blow up (warning "simulation is unstable"),
        # which restarts its clock: the state looks healthy, so diverged envs are recognised by their time.
        self.diverged = torch.from_numpy(np.abs(self.state[:, 0] - expected_time) > 0.5 * self.model.opt.timestep)

    def sanitize(self, envs: torch.Tensor) -> None:
        """Replace NaN and inf in these envs' state ([N] bool mask) by 0 and clear their records (diverged envs,
        about to reset)."""
        rows = np.flatnonzero(torch.as_tensor(envs).numpy())
        if len(rows) == 0:
            return
        self.state[rows] = np.nan_to_num(self.state[rows], nan=0.0, posinf=0.0, neginf=0.0)
        self.sensor_records[rows] = 0.0
        self.state_records[rows] = 0.0

    def set_qpos_qvel(self, env_ids: torch.Tensor, qpos: torch.Tensor, qvel: torch.Tensor) -> None:
        """Reset the chosen envs to (qpos, qvel) at rest: time 0, no actuator state, no warm start.

        A forward pass then fills their sensors and substep records, so that what an env reads right after a reset
        (foot positions, contacts, COM) describes the new state, not zeros or the previous episode.
        """
        rows = torch.as_tensor(env_ids).numpy()
        state = self.state[rows]
        state[:] = 0.0
        state[:, self.qpos_slice] = np.asarray(qpos, dtype=np.float64)
        state[:, self.qvel_slice] = np.asarray(qvel, dtype=np.float64)
        self.state[rows] = state
        self.forward(rows)

    def forward(self, env_ids) -> None:
        """mj_forward on the chosen envs' states: their sensors, for every substep slot, and their substep states."""
        data = self.datas[0]
        for i in np.asarray(env_ids).reshape(-1):
            model = self.models[i]
            mujoco.mj_setState(model, data, self.state[i], STATE_SPEC)
            mujoco.mj_forward(model, data)
            self.sensor_records[i] = data.sensordata
            self.state_records[i] = self.state[i]
