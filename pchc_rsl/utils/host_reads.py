"""Finding the places where code makes a GPU wait for the host: host syncs, counted without a GPU.

On a GPU, torch's sync debug mode (``torch.cuda.set_sync_debug_mode("warn")``) reports syncs as they happen. On a
CPU nothing syncs, yet the same code would. ``HostReads`` records, with the line of our code that made it, every
operation that syncs on CUDA:

- a value read on the host: ``item()``, ``bool``/``int``/``float`` of a tensor (a Python ``if`` on a tensor),
  ``torch.equal``, ``.tolist()``, ``.numpy()``, ``.cpu()``; also inside torch: ``torch.normal`` with a tensor std
  (it checks std >= 0 on the host; ``torch.distributions.Normal.sample`` calls it) and linalg's error checks;
- an output whose shape depends on the data: ``nonzero``, boolean-mask indexing and assignment (but ``t[mask] =
  number``, which runs as ``masked_fill_``), ``masked_select``, ``unique``, ``bincount``, ``repeat_interleave``
  without ``output_size``;
- a copy from the host: a tensor made from a Python list or a numpy array (``torch.tensor([...])``, indexing with
  a list, ``torch.as_tensor(array)``: the GPU receives it with a blocking copy), a number made a tensor on a
  device (``torch.tensor(1.0, device=...)``), and any copy whose source and destination devices differ.

Two torch modes see them: a dispatch mode for the aten operations, a function mode for the Python calls that never
reach aten on the CPU (``.cpu()`` of a CPU tensor returns it as it is). A copy between devices shows only where
there are two: on the CPU, a tensor moved to the env's device (``.to(device)``) cannot be told from one already there.
"""

from __future__ import annotations

import contextlib
import traceback
from dataclasses import dataclass

import torch
from torch.overrides import TorchFunctionMode
from torch.utils._python_dispatch import TorchDispatchMode

aten = torch.ops.aten

SYNCING_OPS = {
    aten._local_scalar_dense.default: "value read",
    aten.item.default: "value read",
    aten.is_nonzero.default: "value read",
    aten.equal.default: "value read",
    aten.nonzero.default: "data-dependent shape",
    aten.argwhere.default: "data-dependent shape",
    aten.masked_select.default: "data-dependent shape",
    aten._unique.default: "data-dependent shape",
    aten._unique2.default: "data-dependent shape",
    aten.unique_dim.default: "data-dependent shape",
    aten.unique_consecutive.default: "data-dependent shape",
    aten.bincount.default: "data-dependent shape",
    aten.normal.Tensor_Tensor: "value read",
    aten.normal.float_Tensor: "value read",
    aten._linalg_check_errors.default: "value read",
}
"""aten operations that wait for the device on CUDA, whatever their arguments. (``bool(t)`` reaches the dispatch
mode as ``is_nonzero`` or, decomposed, as ``_local_scalar_dense``: one of them, so it counts once.)"""

HOST_FUNCTIONS = {"cpu": "copy to host", "numpy": "copy to host", "tolist": "copy to host"}
"""Python-level Tensor methods that hand data to the host (on the CPU they never reach aten)."""

FROM_HOST = {torch.tensor, torch.as_tensor}
"""Constructors that copy a number onto a device when given one (lists and arrays show as aten ``lift_fresh``)."""


def _has_mask(index) -> bool:
    if isinstance(index, torch.Tensor):
        return index.dtype == torch.bool
    if isinstance(index, (tuple, list)):
        return any(_has_mask(i) for i in index)
    return False


def _from_host(data, kwargs) -> bool:
    """Whether a constructor copies a number to a device (kept on the host, a 0-dim tensor in a GPU operation is
    read as a number: no copy)."""
    return isinstance(data, (bool, int, float)) and kwargs.get("device") is not None


def _devices(args) -> set[str]:
    return {a.device.type for a in args if isinstance(a, torch.Tensor)}


def syncing_kind(func, args, kwargs) -> str | None:
    """What kind of host sync this aten call makes on CUDA, or None."""
    kind = SYNCING_OPS.get(func)
    if kind is not None:
        return kind
    packet = func.overloadpacket
    if packet in (aten.index, aten.index_put, aten.index_put_, aten._index_put_impl_) and _has_mask(args[1]):
        masked_fill = packet is not aten.index and len([i for i in args[1] if i is not None]) == 1 and args[2].dim() == 0
        return None if masked_fill else "boolean mask"  # ``t[mask] = number`` runs as masked_fill_: no wait
    if func in (aten.repeat_interleave.Tensor, aten.repeat_interleave.self_Tensor) and kwargs.get(
            "output_size") is None:
        return "data-dependent shape"
    if packet is aten.lift_fresh and args[0].dim() > 0:
        return "copy from host"
    if packet is aten._to_copy:
        target = kwargs.get("device")
        if target is not None and torch.device(target).type != args[0].device.type:
            return "copy between devices"
    if packet is aten.copy_ and len(_devices(args[:2])) > 1:
        return "copy between devices"
    return None


@dataclass
class HostRead:
    function: str
    where: str
    """``file:line`` of the innermost frame outside torch, tensordict and this module."""
    kind: str = ""


class _Dispatch(TorchDispatchMode):
    def __init__(self, owner: HostReads) -> None:
        super().__init__()
        self.owner = owner

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        if not self.owner._paused:
            kind = syncing_kind(func, args, kwargs)
            if kind is not None:
                self.owner.reads.append(HostRead(func.overloadpacket.__name__, _caller(), kind))
        return func(*args, **kwargs)


class HostReads(TorchFunctionMode):
    """Records every host sync made inside ``with HostReads() as reads:`` (``reads.reads``, in order);
    ``paused()`` leaves a stretch out (e.g. C MuJoCo's own numpy transfers, which a device physics does not make)."""

    def __init__(self) -> None:
        super().__init__()
        self.reads: list[HostRead] = []
        self._paused = 0
        self._dispatch = _Dispatch(self)

    def __enter__(self):
        self._dispatch.__enter__()
        return super().__enter__()

    def __exit__(self, *exc):
        try:
            return super().__exit__(*exc)
        finally:
            self._dispatch.__exit__(*exc)

    def __torch_function__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        if not self._paused:
            name = getattr(func, "__name__", "")
            if name in HOST_FUNCTIONS:
                self.reads.append(HostRead(name, _caller(), HOST_FUNCTIONS[name]))
            elif func in FROM_HOST and args and _from_host(args[0], kwargs):
                self.reads.append(HostRead(func.__name__, _caller(), "copy from host"))
        return func(*args, **kwargs)

    @contextlib.contextmanager
    def paused(self):
        self._paused += 1
        try:
            yield
        finally:
            self._paused -= 1

    def where(self) -> list[str]:
        """``function at file:line`` of each read, in order."""
        return [f"{r.function} at {r.where}" for r in self.reads]


def _caller() -> str:
    skip = ("/torch/", "/tensordict/", "host_reads.py", "/contextlib.py")
    for frame in reversed(traceback.extract_stack()[:-2]):
        if not any(part in frame.filename for part in skip):
            return f"{'/'.join(frame.filename.rsplit('/', 2)[-2:])}:{frame.lineno}"
    return "?"
