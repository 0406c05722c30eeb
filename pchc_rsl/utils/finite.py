"""Finding non-finite (NaN or inf) numbers in what training produces, so that they stop a run or an export early."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import torch


def first_non_finite_tensor(named: Iterable[tuple[str, torch.Tensor]]) -> str | None:
    """Name of the first floating-point tensor holding NaN or inf, e.g. from ``module.named_parameters()``."""
    for name, tensor in named:
        if tensor.is_floating_point() and not torch.isfinite(tensor).all():
            return name
    return None


def first_non_finite_module_tensor(module: torch.nn.Module) -> str | None:
    """Name of the first parameter or buffer of ``module`` holding NaN or inf (normaliser statistics included)."""
    found = first_non_finite_tensor(module.named_parameters())
    return found if found is not None else first_non_finite_tensor(module.named_buffers())


def first_non_finite_value(values: Mapping[str, float]) -> str | None:
    """Key of the first non-finite number in a dict of scalars (e.g. the losses of an update)."""
    for key, value in values.items():
        if isinstance(value, (int, float)) and not math.isfinite(value):
            return key
    return None


class RolloutNaNCheck:
    """rsl-rl's ``check_nan`` (NaN in an observation group, the rewards or the dones) without a host sync per step.

    rsl-rl reads six flags back from the device at every env step; on a GPU each read stalls the step. Here each
    step ORs its flags into a device tensor, and ``raise_if_any`` reads them once per rollout, before anything of
    that rollout is learned from. The error is rsl-rl's ValueError, naming the first source that held NaN.
    """

    def __init__(self) -> None:
        self.names: list[str] | None = None
        self.flags: torch.Tensor | None = None

    def add(self, obs, rewards: torch.Tensor, dones: torch.Tensor) -> None:
        """Record whether this step's outputs hold NaN (on the device: nothing waits)."""
        tensors = [*obs.values(), rewards, dones]
        if self.names is None:
            self.names = [f"the observation group '{key}'" for key in obs.keys()] + ["the rewards", "the dones"]
        flags = torch.stack([torch.isnan(t).any() for t in tensors])
        self.flags = flags if self.flags is None else self.flags | flags

    def raise_if_any(self) -> None:
        """Raise ValueError if a recorded step held NaN (one host sync); then start over."""
        flags, self.flags = self.flags, None
        if flags is None or not bool(flags.any()):
            return
        source = self.names[int(flags.int().argmax())]
        raise ValueError(f"{source} returned by the environment contains NaN values in this rollout. This usually "
                         "indicates a bug in the environment's step(), reset() or reward computation.")
