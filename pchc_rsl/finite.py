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
