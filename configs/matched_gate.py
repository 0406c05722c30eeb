"""The learned-gate ablation sized like the PCI actor it is compared with: as many experts, as many parameters.

A gated mixture is PCI's experts plus a gate network, so with PCI's expert widths it has more parameters, and on the
three-objective tasks PCI's default lattice has more experts than the gate's default five. Matching both means a
difference between them comes from the routing, not from the size. The gate keeps its own width; the experts' hidden
widths shrink until the total is as close to PCI's as a whole width allows (e.g. mo-halfcheetah-v5, [64, 64] experts:
PCI 29,156 parameters, gate with [62, 62] experts 29,231, +0.3%; mo-hopper-v5, six experts: 31,893 and 31,503,
-1.2%).
"""

from __future__ import annotations

import copy

import torch
from tensordict import TensorDict

from rsl_rl.utils import resolve_callable

from pchc_rsl.configs.base import ModelConfig, select_actor


def parameter_count(module: torch.nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())


def build_actor(model: ModelConfig, obs: TensorDict, obs_groups: dict, num_actions: int) -> torch.nn.Module:
    """The actor rsl-rl would build from this config for these observations."""
    kwargs = model.to_dict()
    cls = resolve_callable(kwargs.pop("class_name"))
    return cls(obs, obs_groups, "actor", num_actions, **kwargs)


def sized_like(target: int, model: ModelConfig, obs: TensorDict, obs_groups: dict, num_actions: int,
               widest: int) -> tuple[list[int], int]:
    """The expert hidden widths (``model.hidden_dims`` scaled together, at most ``widest``) whose actor's parameter
    count is closest to ``target``, and that count."""
    model = copy.deepcopy(model)
    shape = list(model.hidden_dims)
    best = None
    for width in range(1, widest + 1):
        model.hidden_dims = [max(1, round(h * width / max(shape))) for h in shape]
        count = parameter_count(build_actor(model, obs, obs_groups, num_actions))
        if best is None or abs(count - target) < abs(best[1] - target):
            best = (list(model.hidden_dims), count)
    return best


def matched_pci_variant(pci: ModelConfig, variant: ModelConfig, obs: TensorDict, obs_groups: dict,
                        num_actions: int) -> tuple[ModelConfig, dict]:
    """A PCI variant that adds networks (residual experts' shared network, a gate on the Beta density) with expert
    widths that make its parameter count the PCI actor's; and {"pci": count, "matched": count,
    "expert_hidden_dims": [...]}."""
    target = parameter_count(build_actor(pci, obs, obs_groups, num_actions))
    variant = copy.deepcopy(variant)
    variant.hidden_dims, count = sized_like(target, variant, obs, obs_groups, num_actions, max(pci.hidden_dims))
    return variant, {"pci": target, "matched": count, "expert_hidden_dims": list(variant.hidden_dims)}


def matched_gate(pci: ModelConfig, obs: TensorDict, obs_groups: dict, num_actions: int) -> tuple[ModelConfig, dict]:
    """A GatedMoEActor config with the PCI actor's expert count and the expert width whose total parameter count is
    closest to the PCI actor's; and {"pci": count, "gated": count, "num_experts": E, "expert_hidden_dims": [...]}."""
    pci_actor = build_actor(pci, obs, obs_groups, num_actions)
    target = parameter_count(pci_actor)
    gated = copy.deepcopy(pci)
    select_actor(gated, "gated")
    gated.kwargs["num_experts"] = int(pci_actor.mlp.positions.shape[0])
    best = sized_like(target, gated, obs, obs_groups, num_actions, max(pci.hidden_dims))
    gated.hidden_dims = best[0]
    return gated, {"pci": target, "gated": best[1], "num_experts": gated.kwargs["num_experts"],
                   "expert_hidden_dims": best[0]}
