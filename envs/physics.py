"""Batched C MuJoCo: N copies of one model stepped together on native threads (mujoco.rollout, GIL released).

The whole interface an environment needs, kept small so a GPU backend (MuJoCo Warp) can sit behind it:
set the full physics state of some envs, step all envs K substeps with a held control, read the state and the
sensors of every substep.
"""

from __future__ import annotations

import mujoco
import numpy as np
from mujoco import rollout

STATE_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS


class BatchedMuJoCo:
    """N environments of one MjModel (or N same-sized models for per-env physical randomisation)."""

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
        data = mujoco.MjData(m)
        mujoco.mj_getState(m, data, self.state[0], STATE_SPEC)
        self.state[:] = self.state[0]
        self.substep_states = np.zeros((num_envs, substeps, self.nstate))
        self.substep_sensors = np.zeros((num_envs, substeps, m.nsensordata))
        # the control vector: ctrl, then (optionally) xfrc_applied, the Cartesian force/torque on every body
        self.control_spec = mujoco.mjtState.mjSTATE_CTRL
        width = m.nu
        if with_body_forces:
            self.control_spec |= mujoco.mjtState.mjSTATE_XFRC_APPLIED
            width += 6 * m.nbody
        self.control = np.zeros((num_envs, substeps, width))
        self.body_forces = np.zeros((num_envs, m.nbody, 6)) if with_body_forces else None
        self.diverged = np.zeros(num_envs, dtype=bool)
        """Envs whose physics MuJoCo had to reset during the last step."""

    def step(self, ctrl: np.ndarray) -> None:
        """Advance every env ``substeps`` physics steps holding ``ctrl`` [N, nu] (and ``body_forces`` [N, nbody, 6]
        if enabled); fills substep_states and substep_sensors."""
        nu = self.model.nu
        expected_time = self.state[:, 0] + self.substeps * self.model.opt.timestep
        self.control[:, :, :nu] = ctrl[:, None, :]
        if self.body_forces is not None:
            self.control[:, :, nu:] = self.body_forces.reshape(self.num_envs, 1, -1)
        self.runner.rollout(
            self.models, self.datas, self.state, self.control, control_spec=self.control_spec, nstep=self.substeps,
            state=self.substep_states, sensordata=self.substep_sensors, skip_checks=True,
        )
        self.state[:] = self.substep_states[:, -1]
        # MuJoCo resets an env's data by itself when its accelerations blow up (warning "simulation is unstable"),
        # which restarts its clock: the state looks healthy, so diverged envs are recognised by their time.
        self.diverged = np.abs(self.state[:, 0] - expected_time) > 0.5 * self.model.opt.timestep

    @property
    def qpos(self) -> np.ndarray:
        return self.state[:, self.qpos_slice]

    @property
    def qvel(self) -> np.ndarray:
        return self.state[:, self.qvel_slice]

    def sensor(self, name: str, substep: int | slice = -1) -> np.ndarray:
        """A named sensor's values at a substep (default: the last) or over a slice of substeps."""
        sensor = self.model.sensor(name)
        adr, dim = int(sensor.adr[0]), int(sensor.dim[0])
        return self.substep_sensors[:, substep, adr : adr + dim]

    def sensor_columns(self, name: str) -> slice:
        sensor = self.model.sensor(name)
        return slice(int(sensor.adr[0]), int(sensor.adr[0] + sensor.dim[0]))

    def set_qpos_qvel(self, env_ids: np.ndarray, qpos: np.ndarray, qvel: np.ndarray) -> None:
        """Reset the chosen envs to (qpos, qvel) at rest: time 0, no actuator state, no warm start.

        A forward pass then fills their sensors and substep records, so that what an env reads right after a reset
        (foot positions, contacts, COM) describes the new state, not zeros or the previous episode.
        """
        state = self.state[env_ids]
        state[:] = 0.0
        state[:, self.qpos_slice] = qpos
        state[:, self.qvel_slice] = qvel
        self.state[env_ids] = state
        self.forward(env_ids)

    def forward(self, env_ids: np.ndarray) -> None:
        """mj_forward on the chosen envs' states: their sensors, for every substep slot, and their substep states."""
        data = self.datas[0]
        for i in np.asarray(env_ids).reshape(-1):
            model = self.models[i]
            mujoco.mj_setState(model, data, self.state[i], STATE_SPEC)
            mujoco.mj_forward(model, data)
            self.substep_sensors[i] = data.sensordata
            self.substep_states[i] = self.state[i]
