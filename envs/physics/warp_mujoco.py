"""Batched MuJoCo Warp: the whole batch on one device (a GPU, or Warp's slow CPU device), behind BatchedMuJoCo's
interface (``batched_mujoco.py``).

The env reads torch views of Warp's own arrays (``wp.to_torch``: no copies), so observations and rewards stay on
the device. Per-env physical randomisation keeps its bounded set of model variants: every model field in which the
variants differ gets a leading batch dimension of V, and world i reads variant i mod V, as on the C backend. On a
CUDA device the substep loop and a reset's forward pass are each captured once as a CUDA graph, on a stream made
for it (CUDA refuses to capture on the legacy default stream torch uses), and replayed (as mjlab does).

Differences from C MuJoCo: Warp computes in float32, and it does not reset a diverged world by itself (a diverged
world shows as non-finite or absurd velocities, which the env catches and resets). A reset runs a forward pass on
every world (Warp has no per-world forward); it leaves the state of the other worlds untouched.

Warp's buffers are fixed per world (``warp_settings.py``): what does not fit is dropped. After every physics step a
small kernel folds the peaks (constraint rows, contacts, solver iterations), the steps that stopped at the solver's
iteration limit and the overflow flags into a device record that training reads once per iteration; mujoco_warp's
own printf per world and step is switched off.
"""

from __future__ import annotations

import dataclasses
import logging

import mujoco
import numpy as np
import torch

from pchc_rsl.envs.physics.warp_device import (TESTED_MUJOCO_WARP, cuda_graph_problem, mujoco_warp_version_note,
                                       require_warp_cuda)
from pchc_rsl.envs.physics.warp_settings import WarpSettings
from pchc_rsl.utils.physics_overflow import PhysicsOverflow

try:
    import mujoco_warp as mjw
    import warp as wp
except ImportError as error:  # the optional extra
    raise ImportError(
        "--physics warp needs MuJoCo Warp: pip install -e \".[warp]\" (mujoco-warp matching mujoco "
        f"{mujoco.__version__}). ({error})"
    ) from None

BUFFER_OVERFLOWS = {
    "NEFC": "constraint rows (njmax)",
    "NJMAX_NNZ": "constraint Jacobian non-zeros (njmax * nv)",
    "BROADPHASE": "broadphase collision pairs (naconmax)",
    "NARROWPHASE": "contacts (naconmax)",
    "CCD": "convex collision contacts (naccdmax)",
    "NVMAX": "active degrees of freedom (nvmax)",
}
"""Warp's overflow flags that mean results were dropped. The solver's iteration limits are not errors (the step
stops at the limit, as C MuJoCo does): they are counted instead (``solver_limit_share``)."""

SETTING_OF = {"NEFC": "constraints_per_env", "NJMAX_NNZ": "constraints_per_env", "BROADPHASE": "contacts_per_env",
              "NARROWPHASE": "contacts_per_env", "CCD": "contacts_per_env"}
"""The WarpSettings field (``env.warp.<field>``) that sizes each buffer."""

SOLVER_LIMIT = wp.constant(int(mjw.OverflowType.ITERATIONS))
LINESEARCH_LIMIT = wp.constant(int(mjw.OverflowType.LS_ITERATIONS))
LIMIT_BITS = wp.constant(int(mjw.OverflowType.ITERATIONS) | int(mjw.OverflowType.LS_ITERATIONS))

PEAK_ROWS, PEAK_ITERATIONS, PEAK_CONTACTS, PEAK_PAIRS, SOLVER_HITS, LINESEARCH_HITS, FLAGS = (
    wp.constant(slot) for slot in range(7))
"""Slots of the device record folded after every physics step (``_fold``)."""


@wp.kernel
def _fold(nefc: wp.array(dtype=int), niter: wp.array(dtype=int), nacon: wp.array(dtype=int),
          ncollision: wp.array(dtype=int), overflow: wp.array(dtype=int), record: wp.array(dtype=int)):
    """One thread per world, after each physics step: the peaks of constraint rows (counted also past the buffer),
    solver iterations and contacts (all worlds); one count per world that stopped at the solver's or the line
    search's iteration limit (the flag is cleared, so the next step counts again); the buffer overflow flags."""
    world = wp.tid()
    wp.atomic_max(record, PEAK_ROWS, nefc[world])
    wp.atomic_max(record, PEAK_ITERATIONS, niter[world])
    if world == 0:
        wp.atomic_max(record, PEAK_CONTACTS, nacon[0])
        wp.atomic_max(record, PEAK_PAIRS, ncollision[0])
    flags = overflow[world]
    if (flags & SOLVER_LIMIT) != 0:
        wp.atomic_add(record, SOLVER_HITS, 1)
    if (flags & LINESEARCH_LIMIT) != 0:
        wp.atomic_add(record, LINESEARCH_HITS, 1)
    if (flags & LIMIT_BITS) != 0:
        overflow[world] = flags & ~LIMIT_BITS
    if (flags & ~LIMIT_BITS) != 0:
        wp.atomic_or(record, FLAGS, flags & ~LIMIT_BITS)


def batchable_fields() -> list[str]:
    """Model fields MuJoCo Warp can give a leading batch dimension (their array spec starts with '*')."""
    try:
        from mujoco_warp._src.warp_util import is_array_spec
    except ImportError as error:
        raise ImportError(f"mujoco-warp {getattr(mjw, '__version__', '?')} lacks the helper this project reads "
                          f"({error}); install a tested version: pip install mujoco-warp=={TESTED_MUJOCO_WARP[-1]}"
                          ) from None
    return [f.name for f in dataclasses.fields(mjw.Model)
            if is_array_spec(f.type) and getattr(f.type, "shape", ())[:1] == ("*",)]


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
    """N environments as N Warp worlds of one model (see the module docstring for randomised variants, and
    ``warp_settings.py`` for the buffer sizes and solver settings)."""

    def __init__(self, models: mujoco.MjModel | list[mujoco.MjModel], num_envs: int, substeps: int,
                 device: str = "cuda:0", with_body_forces: bool = False, settings: WarpSettings | None = None) -> None:
        self.models = models if isinstance(models, list) else [models] * num_envs
        if len(self.models) != num_envs:
            raise ValueError(f"Got {len(self.models)} models for {num_envs} envs.")
        self.settings = settings = settings or WarpSettings()
        settings.check()
        self.model = self.models[0]
        self.num_envs, self.substeps = num_envs, substeps
        self.device = str(torch.device(device))
        wp.config.log_level = max(wp.config.log_level, logging.WARNING)  # no line per kernel module loaded
        wp.init()
        if torch.device(self.device).type == "cuda":
            require_warp_cuda(self.device)
        note = mujoco_warp_version_note()
        if note:
            logging.getLogger(__name__).warning(note)
        self.wp_device = wp.get_device(self.device)
        variants = _variants(self.models)
        m = self.model
        with wp.ScopedDevice(self.wp_device):
            batched = differing_fields(variants)
            self.batched_fields = batched
            self.wp_model = mjw.put_model(m, batch_sizes={name: len(variants) for name in batched})
            self.wp_model.opt.iterations = settings.solver_iterations
            self.wp_model.opt.ls_iterations = settings.linesearch_iterations
            # no printf per world and step when the solver stops at its limit (or a buffer overflows): the limit
            # hits are counted and overflows raised instead. Read when the kernels are built, so set before any step
            self.wp_model.opt.warn_overflow = 0
            for name in batched:
                field = wp.to_torch(getattr(self.wp_model, name))
                values = np.stack([getattr(v, name) for v in variants])
                field.copy_(torch.from_numpy(values).reshape(field.shape))
            self.data = mjw.make_data(m, nworld=num_envs, nconmax=settings.contacts_per_env,
                                      njmax=settings.constraints_per_env)
            self._sensor_records = wp.zeros((substeps, num_envs, m.nsensordata), dtype=float)
            self._qvel_records = wp.zeros((substeps, num_envs, m.nv), dtype=float)
            self._ctrl_substeps = wp.zeros((substeps, num_envs, m.nu), dtype=float)
            self._record = wp.zeros(FLAGS + 1, dtype=int)
        d = self.data
        # torch views of Warp's arrays, made once (wp.to_torch builds a new tensor object at every call)
        self.qpos, self.qvel = wp.to_torch(d.qpos), wp.to_torch(d.qvel)
        self.substep_sensors = wp.to_torch(self._sensor_records).permute(1, 0, 2)
        self.substep_qvel = wp.to_torch(self._qvel_records).permute(1, 0, 2)
        self.body_forces = wp.to_torch(d.xfrc_applied) if with_body_forces else None
        self._ctrl_view = wp.to_torch(self._ctrl_substeps)  # [K, N, nu]: read by each substep
        self._sensordata = wp.to_torch(d.sensordata)
        self._reset_fields = [v for v in (wp.to_torch(f) for f in (d.act, d.qacc_warmstart, d.time)) if v.numel()]
        self._state_fields = [v for v in (wp.to_torch(f) for f in (d.qpos, d.qvel, d.act, d.qacc_warmstart))
                              if v.numel()]
        self._record_view = wp.to_torch(self._record)
        """Folded on the device after every physics step since the last report: the slots named above."""
        self._world_steps = 0
        """Solver runs of all worlds (physics steps, and a reset's forward pass) since the last report, counted on
        the host: the share of limit hits needs no device read."""
        self.diverged = torch.zeros(num_envs, dtype=torch.bool, device=self.device)
        """Always False: Warp does not reset a diverged world (the env's NaN and velocity checks catch it)."""
        self._graphs: dict[str, object] = {}
        """CUDA graphs by name: the substep loop, and the forward pass of a reset."""
        self._capture_stream = None
        self._torch_streams: dict[int, object] = {}
        """Warp's handle of each torch stream seen, made once."""
        self._started = False
        """Whether the first reset (the start states) was checked against the buffers."""
        self.eager_reason = cuda_graph_problem(self.wp_device) if self.wp_device.is_cuda else None
        """Why a CUDA device runs the physics eagerly instead of as captured graphs (None: graphs)."""
        if self.wp_device.is_cuda:
            self._capture_stream = wp.Stream(self.wp_device)
            if self.eager_reason is None:
                wp.set_mempool_enabled(self.wp_device, True)  # a graph's allocations come from Warp's pool
            else:
                logging.getLogger(__name__).warning("MuJoCo Warp runs eagerly on %s, without CUDA graphs: %s",
                                                    self.device, self.eager_reason)
        self._forward_and_record(slice(None))
        self._record_view.zero_()  # the model's own pose (qpos0) is no state the env simulates
        self._world_steps = 0

    def _fold_record(self) -> None:
        d = self.data
        wp.launch(_fold, dim=self.num_envs, inputs=[d.nefc, d.solver_niter, d.nacon, d.ncollision],
                  outputs=[d.overflow, self._record])

    def _substeps(self) -> None:
        d, n = self.data, self.num_envs
        for k in range(self.substeps):
            wp.copy(d.ctrl, self._ctrl_substeps, src_offset=k * n * self.model.nu, count=n * self.model.nu)
            mjw.step(self.wp_model, d)
            self._fold_record()
            wp.copy(self._sensor_records, d.sensordata, dest_offset=k * n * self.model.nsensordata,
                    count=n * self.model.nsensordata)
            wp.copy(self._qvel_records, d.qvel, dest_offset=k * n * self.model.nv, count=n * self.model.nv)

    def step(self, ctrl: torch.Tensor) -> None:
        """Advance every world ``substeps`` physics steps holding ``ctrl`` [N, nu], or with one control per substep
        [N, K, nu] (an action delay), and ``body_forces``."""
        per_substep = self._ctrl_view
        per_substep.copy_(ctrl.permute(1, 0, 2) if ctrl.ndim == 3 else ctrl.unsqueeze(0).expand_as(per_substep))
        self._launch("substeps", self._substeps)
        self._world_steps += self.substeps * self.num_envs

    def overflow_report(self) -> dict[str, float]:
        """Since the last call, read once (one host sync): the largest constraint rows of one world, solver
        iterations and contacts (all worlds), and the share of solver runs (one per world and physics step or reset)
        that stopped at the solver's or the line search's iteration limit (%); PhysicsOverflow when a buffer
        overflowed (results were dropped)."""
        record = self._record_view.tolist()
        self._record_view.zero_()
        world_steps, self._world_steps = max(self._world_steps, 1), 0
        report = {"max_constraint_rows": record[PEAK_ROWS], "constraint_rows_capacity": self.data.njmax,
                  "max_solver_iterations": record[PEAK_ITERATIONS],
                  "solver_iterations_limit": self.wp_model.opt.iterations,
                  "solver_limit_share": 100.0 * record[SOLVER_HITS] / world_steps,
                  "linesearch_limit_share": 100.0 * record[LINESEARCH_HITS] / world_steps,
                  "max_contacts": record[PEAK_CONTACTS], "contacts_capacity": self.data.naconmax}
        problem = self._overflow_problem(record)
        if problem:
            raise PhysicsOverflow(f"{problem}; peaks since the last report: {report}. The physics dropped contacts "
                                  "or constraint rows, so training on it would be wrong.")
        return {key: float(value) for key, value in report.items()}

    def _overflow_problem(self, record: list[int]) -> str | None:
        """What overflowed and the size to set (``env.warp.<field>=...``), or None. Warp counts constraint rows and
        contacts also past its buffers, so the sizes needed are known."""
        flags = record[FLAGS]
        if record[PEAK_ROWS] > self.data.njmax:
            flags |= int(mjw.OverflowType.NEFC)  # a forward pass (a reset) counts the rows but sets no flag
        if max(record[PEAK_CONTACTS], record[PEAK_PAIRS]) > self.data.naconmax:
            flags |= int(mjw.OverflowType.NARROWPHASE)
        names = [name for name in BUFFER_OVERFLOWS if flags & int(getattr(mjw.OverflowType, name, 0))]
        if not names:
            return None
        rows = record[PEAK_ROWS]
        contacts = -(-max(record[PEAK_CONTACTS], record[PEAK_PAIRS]) // self.num_envs)
        needed = {"constraints_per_env": (self.settings.constraints_per_env, rows, f"{rows} rows in one world"),
                  "contacts_per_env": (self.settings.contacts_per_env, contacts, f"{contacts} per world on average")}
        advice = []
        for setting in dict.fromkeys(SETTING_OF.get(name) for name in names if name in SETTING_OF):
            now, peak, said = needed[setting]
            advice.append(f"env.warp.{setting}={max(2 * now, _round_up(2 * peak))} (now {now}; needed {said})")
        buffers = ", ".join(f"{BUFFER_OVERFLOWS[name]} [{name}]" for name in names)
        return (f"MuJoCo Warp overflowed its buffers of {buffers}" +
                (f"; set {' and '.join(advice)}" if advice else ""))

    def check_start(self, qpos: torch.Tensor, qvel: torch.Tensor) -> None:
        """Refuse buffers too small for the task's start (at the first reset, one host read): the rows and contacts
        the start states need now (Warp's own count, every world) and once one of them has settled on the floor
        (C MuJoCo, 0.3 s holding its pose). ValueError in one line naming the setting and the size needed."""
        record = self._record_view.tolist()
        rows, contacts = settled_needs(self.models[0], qpos[0].double().cpu().numpy(), qvel[0].double().cpu().numpy())
        needs = {"constraints_per_env": (max(rows, record[PEAK_ROWS]), "constraint rows in one world"),
                 "contacts_per_env": (max(contacts, -(-max(record[PEAK_CONTACTS], record[PEAK_PAIRS]) //
                                                      self.num_envs)), "contacts in one world")}
        for setting, (needed, what) in needs.items():
            given = getattr(self.settings, setting)
            if needed > given:
                raise ValueError(f"env.warp.{setting}={given} is too small for this task: one robot at its start "
                                 f"needs {needed} {what}; set env.warp.{setting} to at least {needed}, better "
                                 f"{_round_up(2 * needed)} (a robot lying on the floor needs about twice what a "
                                 f"standing one does).")

    def _launch(self, name: str, work_fn) -> None:
        """Run ``work_fn`` (Warp launches only): eagerly on the CPU; on CUDA captured once as a graph named ``name``
        and replayed from then on (the first call runs it eagerly, which also loads every kernel before capture).

        CUDA cannot capture on the legacy default stream, which torch uses unless told otherwise: graphs are captured
        on and replayed from a stream of their own, ordered after torch's work (the control copy, a reset's writes)
        and before torch's next reads (observations) by explicit waits."""
        with wp.ScopedDevice(self.wp_device):
            if not self.wp_device.is_cuda or self.eager_reason is not None:
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
        if not self.wp_device.is_cuda:
            return None
        current = torch.cuda.current_stream(self.device)
        if current.cuda_stream not in self._torch_streams:
            self._torch_streams[current.cuda_stream] = wp.stream_from_torch(current)
        return self._torch_streams[current.cuda_stream]

    def sanitize(self, envs: torch.Tensor) -> None:
        """Zero the non-finite state, warm start and records of these worlds ([N] bool mask: diverged worlds,
        about to reset), by masks over all worlds so that nothing waits on the device."""
        rows = envs.to(self.device)
        for values in self._state_fields:
            clean = torch.nan_to_num(values, nan=0.0, posinf=0.0, neginf=0.0)
            values.copy_(torch.where(rows.view(-1, *([1] * (values.dim() - 1))), clean, values))
        for records in (self.substep_sensors, self.substep_qvel):
            records.masked_fill_(rows.view(-1, *([1] * (records.dim() - 1))), 0.0)

    def set_qpos_qvel(self, env_ids: torch.Tensor, qpos: torch.Tensor, qvel: torch.Tensor) -> None:
        """Reset these worlds to (qpos, qvel) at rest (time 0, no actuator state, no warm start); a forward pass fills
        their sensors and substep records, as on the C backend."""
        ids = torch.as_tensor(env_ids, device=self.device)
        self.qpos[ids] = qpos.to(self.qpos)
        self.qvel[ids] = qvel.to(self.qvel)
        for values in self._reset_fields:
            values[ids] = 0.0
        self._forward_and_record(ids)
        if not self._started:  # the env's first reset: its start states
            self._started = True
            self.check_start(qpos, qvel)

    def _forward(self) -> None:
        mjw.forward(self.wp_model, self.data)
        self._fold_record()

    def _forward_and_record(self, ids) -> None:
        """mjw.forward on every world (the state stays), then every substep slot of these worlds' records holds
        their current sensors and joint velocities."""
        self._launch("forward", self._forward)
        self._world_steps += self.num_envs
        self.substep_sensors[ids] = self._sensordata[ids].unsqueeze(1)
        self.substep_qvel[ids] = self.qvel[ids].unsqueeze(1)


def settled_needs(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray, seconds: float = 0.3) -> tuple[int, int]:
    """The most constraint rows and contacts one robot needs from (qpos, qvel) until it has settled: C MuJoCo,
    every position actuator holding its joint where it starts (a standing start lands on its feet, a prone one on
    its front)."""
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel
    joints = model.actuator_trnid[:, 0]
    data.ctrl[:] = qpos[model.jnt_qposadr[joints]]
    rows = contacts = 0
    for _ in range(max(1, round(seconds / model.opt.timestep))):
        mujoco.mj_step(model, data)
        rows, contacts = max(rows, data.nefc), max(contacts, data.ncon)
    return rows, contacts


def _round_up(value: int, to: int = 16) -> int:
    return -(-value // to) * to


def _variants(models: list[mujoco.MjModel]) -> list[mujoco.MjModel]:
    """The distinct models, in order; env i must use variant i mod V (as envs/g1/randomization.py: model_variants makes)."""
    variants = list({id(m): m for m in models}.values())
    if any(models[i] is not variants[i % len(variants)] for i in range(len(models))):
        raise ValueError("WarpMuJoCo needs env i to use model variant i mod V (see envs/g1/randomization.py).")
    return variants
