"""Counting the places where code reads a tensor's value on the host: each one is a device-to-host sync on a GPU.

On a GPU, torch's sync debug mode (``torch.cuda.set_sync_debug_mode("warn")``) reports syncs as they happen. On a
CPU nothing syncs, yet the same code would: ``HostReads`` records, through a torch function mode, every call that
needs a tensor's value on the host (``item``, ``bool``/``int``/``float`` of a tensor, ``nonzero``, ``tolist``,
``numpy``, ``cpu``, indexing with a boolean mask, ``masked_select``, ``unique``), with the line of our code that
made it, so a test without a GPU can count and place them.
"""

from __future__ import annotations

import contextlib
import traceback
from dataclasses import dataclass

import torch
from torch.overrides import TorchFunctionMode

READS_VALUE = frozenset({"item", "__bool__", "__int__", "__float__", "__index__", "nonzero", "argwhere", "tolist",
                         "numpy", "cpu", "masked_select", "unique", "unique_consecutive", "nonzero_static"})
"""Tensor functions that hand a value (or a data-dependent shape) to the host."""


def _is_mask(index) -> bool:
    if isinstance(index, torch.Tensor):
        return index.dtype == torch.bool
    if isinstance(index, tuple):
        return any(_is_mask(i) for i in index)
    return False


@dataclass
class HostRead:
    function: str
    where: str
    """``file:line`` of the innermost frame outside torch, tensordict and this module."""


class HostReads(TorchFunctionMode):
    """Records every host read made inside ``with HostReads() as reads:``; ``paused()`` leaves a stretch out (e.g. C
    MuJoCo's own numpy transfers, which a device physics does not make)."""

    def __init__(self) -> None:
        super().__init__()
        self.reads: list[HostRead] = []
        self._paused = 0

    def __torch_function__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        if not self._paused:
            name = getattr(func, "__name__", "")
            masked = name in ("__getitem__", "__setitem__") and len(args) > 1 and _is_mask(args[1]) and not (
                name == "__setitem__" and not isinstance(args[2], torch.Tensor))
            if name in READS_VALUE or masked:
                self.reads.append(HostRead(f"{name}[mask]" if masked else name, _caller()))
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
    skip = ("/torch/", "/tensordict/", "host_reads.py")
    for frame in reversed(traceback.extract_stack()[:-2]):
        if not any(part in frame.filename for part in skip):
            return f"{frame.filename.rsplit('/', 2)[-2]}/{frame.filename.rsplit('/', 1)[-1]}:{frame.lineno}"
    return "?"
