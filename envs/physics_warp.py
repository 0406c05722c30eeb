"""Batched MuJoCo Warp: the whole batch on one device (a GPU, or Warp's slow CPU device), behind BatchedMuJoCo's
interface (``physics.py``).

The env reads torch views of Warp's own arrays (``wp.to_torch``: no copies), so observations and rewards stay on
the device. Per-env physical randomisation keeps its bounded set of model variants: every model field in which the
variants differ gets a leading batch dimension of V, and world i reads variant i mod V, as on the C backend. On a
CUDA device the substep loop and a reset's forward pass are each captured once as a CUDA graph, on a stream made
for it (CUDA refuses to capture on the legacy default stream torch uses), and replayed (as mjlab does).

Differences from C MuJoCo: Warp computes in float32, and it does not reset a diverged world by itself (a diverged
world shows as non-finite or absurd velocities, which the env catches and resets). A reset runs a forward pass on
every world (Warp has no per-world forward); it leaves the state of the other worlds untouched.
"""

from __future__ import annotations

import logging

import mujoco
import numpy as np
import torch

try:
    import mujoco_warp as mjw
    import warp as wp
except ImportError as error:  # the optional extra
    raise ImportError(
        "--physics warp needs MuJoCo Warp: pip install -e \".[warp]\" (mujoco-warp matching mujoco "
        f"{mujoco.__version__}). ({error})"
    ) from None

def batchable_fields() -> list[str]:
    """Model fields MuJoCo Warp can give a leading batch dimension (their array spec starts with '*')."""
    import dataclasses

    from mujoco_warp._src import warp_util

    return [f.name for f in dataclasses.fields(mjw.Model)
            if warp_util.is_array_spec(f.type) and getattr(f.type, "shape", ())[:1] == ("*",)]


def differing_fields(variants: list[mujoco.MjModel]) -> list[str]:
    """Every batchable model field in which the variants differ: what randomisation sets (friction, masses, gains)
    and what mj_setConst derives from it (subtree masses, body_invweight0, dof_invweight0, actuator_acc0, ...). A
    difference in a Warp model field that cannot be batched is refused: the worlds would silently share variant 0's
    value."""
    first = variants[0]
    warp_fields = {f.name for f in __import__("dataclasses").fields(mjw.Model)}
    batchable = set(batchable_fields())
    differ = [name for name in dir(first) if not name.startswith("_") and name in warp_fields
              and isinstance(getattr(first, name), np.ndarray)
              and any(not np.array_equal(getattr(v, name), getattr(first, name)) for v in variants[1:])]
    unbatchable = [name for name in differ if name not in batchable]
    if unbatchable:
        raise ValueError(f"model variants differ in {unbatchable}, which MuJoCo Warp cannot batch per world.")
    return differ


class WarpMuJoCo:
    """N environments as N Warp worlds of one model (see the module docstring for randomised variants)."""

    def __init__(self, models: mujoco.MjModel | list[mujoco.MjModel], num_envs: int, substeps: int,
                 device: str = "cuda:0", with_body_forces: bool = False, contacts_per_env: int = 64,
                 constraints_per_env: int = 320) -> None:
        self.models = models if isinstance(models, list) else [models] * num_envs
        if len(self.models) != num_envs:
            raise ValueError(f"Got {len(self.models)} models for {num_envs} envs.")
        self.model = self.models[0]
        self.num_envs, self.substeps = num_envs, substeps
        self.device = str(torch.device(device))
        wp.config.log_level = max(wp.config.log_level, logging.WARNING)  # no line per kernel module loaded
        wp.init()
        self.wp_device = wp.get_device(self.device)
        variants = _variants(self.models)
        m = self.model
        with wp.ScopedDevice(self.wp_device):
            batched = differing_fields(variants)
            self.batched_fields = batched
            self.wp_model = mjw.put_model(m, batch_sizes={name: len(variants) for name in batched})
            for name in batched:
                field = wp.to_torch(getattr(self.wp_model, name))
                values = np.stack([getattr(v, name) for v in variants])
                field.copy_(torch.from_numpy(values).reshape(field.shape))
            self.data = mjw.make_data(m, nworld=num_envs, nconmax=contacts_per_env, njmax=constraints_per_env)
            self._sensor_records = wp.zeros((substeps, num_envs, m.nsensordata), dtype=float)
            self._qvel_records = wp.zeros((substeps, num_envs, m.nv), dtype=float)
            self._ctrl_substeps = wp.zeros((substeps, num_envs, m.nu), dtype=float)
        d = self.data
        self.qpos, self.qvel = wp.to_torch(d.qpos), wp.to_torch(d.qvel)
        self.substep_sensors = wp.to_torch(self._sensor_records).permute(1, 0, 2)
        self.substep_qvel = wp.to_torch(self._qvel_records).permute(1, 0, 2)
        self.body_forces = wp.to_torch(d.xfrc_applied) if with_body_forces else None
        self.diverged = torch.zeros(num_envs, dtype=torch.bool, device=self.device)
        """Always False: Warp does not reset a diverged world (the env's NaN and velocity checks catch it)."""
        self._graphs: dict[str, object] = {}
        """CUDA graphs by name: the substep loop, and the forward pass of a reset."""
        self._capture_stream = None
        if self.wp_device.is_cuda:
            self._capture_stream = wp.Stream(self.wp_device)
            wp.set_mempool_enabled(self.wp_device, True)  # a graph's allocations come from Warp's pool
        self._forward_and_record(slice(None))

    def _substeps(self) -> None:
        d, n = self.data, self.num_envs
        for k in range(self.substeps):
            wp.copy(d.ctrl, self._ctrl_substeps, src_offset=k * n * self.model.nu, count=n * self.model.nu)
            mjw.step(self.wp_model, d)
            wp.copy(self._sensor_records, d.sensordata, dest_offset=k * n * self.model.nsensordata,
                    count=n * self.model.nsensordata)
            wp.copy(self._qvel_records, d.qvel, dest_offset=k * n * self.model.nv, count=n * self.model.nv)

    def step(self, ctrl: torch.Tensor) -> None:
        """Advance every world ``substeps`` physics steps holding ``ctrl`` [N, nu], or with one control per substep
        [N, K, nu] (an action delay), and ``body_forces``."""
        per_substep = wp.to_torch(self._ctrl_substeps)  # [K, N, nu]: read by each substep inside the graph
        per_substep.copy_(ctrl.permute(1, 0, 2) if ctrl.ndim == 3 else ctrl.unsqueeze(0).expand_as(per_substep))
        self._launch("substeps", self._substeps)

    def _launch(self, name: str, work_fn) -> None:
        """Run ``work_fn`` (Warp launches only): eagerly on the CPU; on CUDA captured once as a graph named ``name``
        and replayed from then on (the first call runs it eagerly, which also loads every kernel before capture).

        CUDA cannot capture on the legacy default stream, which torch uses unless told otherwise: graphs are captured
        on and replayed from a stream of their own, ordered after torch's work (the control copy, a reset's writes)
        and before torch's next reads (observations) by explicit waits."""
        with wp.ScopedDevice(self.wp_device):
            if not self.wp_device.is_cuda:
                work_fn()
                return
            torch_stream = self._stream()
            work = self._capture_stream
            work.wait_stream(torch_stream)
            with wp.ScopedStream(work, sync_enter=False):
                if name in self._graphs:
                    wp.capture_launch(self._graphs[name], stream=work)
                else:
                    work_fn()
                    with wp.ScopedCapture(device=self.wp_device, stream=work) as capture:  # records, runs nothing
                        work_fn()
                    self._graphs[name] = capture.graph
            torch_stream.wait_stream(work)

    def _stream(self):
        """Torch's current stream on a GPU, for Warp's eager work that torch's reads follow (resets)."""
        return wp.stream_from_torch(torch.cuda.current_stream(self.device)) if self.wp_device.is_cuda else None

    def sanitize(self, envs: torch.Tensor) -> None:
        """Zero the non-finite state, warm start and records of these worlds ([N] bool mask: diverged worlds,
        about to reset), by masks over all worlds so that nothing waits on the device."""
        d = self.data
        rows = envs.to(self.device)
        for field in (d.qpos, d.qvel, d.act, d.qacc_warmstart):
            values = wp.to_torch(field)
            if values.numel():
                clean = torch.nan_to_num(values, nan=0.0, posinf=0.0, neginf=0.0)
                values.copy_(torch.where(rows.view(-1, *([1] * (values.dim() - 1))), clean, values))
        for records in (self.substep_sensors, self.substep_qvel):
            records.masked_fill_(rows.view(-1, *([1] * (records.dim() - 1))), 0.0)

    def set_qpos_qvel(self, env_ids: torch.Tensor, qpos: torch.Tensor, qvel: torch.Tensor) -> None:
        """Reset these worlds to (qpos, qvel) at rest (time 0, no actuator state, no warm start); a forward pass fills
        their sensors and substep records, as on the C backend."""
        d = self.data
        ids = torch.as_tensor(env_ids, device=self.device)
        self.qpos[ids] = qpos.to(self.qpos)
        self.qvel[ids] = qvel.to(self.qvel)
        for field in (d.act, d.qacc_warmstart, d.time):
            values = wp.to_torch(field)
            if values.numel():
                values[ids] = 0.0
        self._forward_and_record(ids)

    def _forward_and_record(self, ids) -> None:
        """mjw.forward on every world (the state stays), then every substep slot of these worlds' records holds
        their current sensors and joint velocities."""
        self._launch("forward", lambda: mjw.forward(self.wp_model, self.data))
        self.substep_sensors[ids] = wp.to_torch(self.data.sensordata)[ids].unsqueeze(1)
        self.substep_qvel[ids] = self.qvel[ids].unsqueeze(1)


def _variants(models: list[mujoco.MjModel]) -> list[mujoco.MjModel]:
    """The distinct models, in order; env i must use variant i mod V (as g1_randomization.model_variants makes)."""
    variants = list({id(m): m for m in models}.values())
    if any(models[i] is not variants[i % len(variants)] for i in range(len(models))):
        raise ValueError("WarpMuJoCo needs env i to use model variant i mod V (see g1_randomization.py).")
    return variants
