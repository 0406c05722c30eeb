"""The networks of several checkpoints of one run, averaged (uniform weight averaging, as in SWA).

Why: late in a run PPO keeps moving the policy, and consecutive checkpoints 50 iterations apart differ by more than
a table's intervals at the ends of the preference range (docs/design.md, "Checkpoint averaging"). The mean of the
actor's (and critics') parameters over a stretch of checkpoints cancels much of that noise. Only checkpoints of one
lineage make sense here: averaging works for nearby points of one training trajectory, not for independently trained
networks.

Floating-point tensors of the actor and critic (weights and observation normalisers) and the value normaliser the
critics predict in are averaged; a normaliser's std is then recomputed as sqrt(var) of its averaged variance (the
mean of the stds is not the std of the mean variance). Everything else (config, iteration, AMP discriminator,
curriculum) is the newest checkpoint's. The optimizer state is dropped, so ``pchc-train --resume`` starts a fresh
one, as for a released policy. The result records what it was averaged from under ``averaged_from`` (run folder,
file and iteration of each).

Weights make it a weighted mean (two checkpoints: a point on the straight line between them in weight space, as
WiSE-FT interpolates a fine-tuned network with the one it started from). ``actor_only`` averages the actor and takes
the critics from the newest checkpoint, for checkpoints whose critics differ in shape (``--init-from`` widens the
critics of a policy trained without ``critic_command_state``); evaluating and playing use the actor alone.

Expert weights (two checkpoints of a mixture actor: PCI or the gated ablation) mix expert by expert: each number is
the second checkpoint's share in one expert, in the order of the actor's ``mlp.positions``; the rest of the actor
(encoder, normaliser, noise) takes the weights, and the critics are the newest checkpoint's (as with ``actor_only``).
Experts that serve different preferences can then be moved by different amounts, as the walker's experiments in
docs/design.md ("Checkpoint averaging") do.
"""

from __future__ import annotations

import os

import torch

from pchc_rsl.runners.checkpoint import load_checkpoint

AVERAGED = ("actor_state_dict", "critic_state_dict", "value_normalizer_state_dict")
EXPERTS = "mlp.experts."
"""The prefix of a mixture actor's batched expert tensors, [expert, ...] each."""


def average_state_dicts(dicts: list[dict], names: list[str], weights: list[float] | None = None,
                        expert_weights: torch.Tensor | None = None) -> dict:
    """(Weighted) mean of each floating-point tensor; other entries (sample counts) from the last. Keys and shapes
    must match. ``expert_weights`` [checkpoint, expert] weighs the expert tensors expert by expert."""
    first = dicts[0]
    for state, name in zip(dicts[1:], names[1:]):
        if state.keys() != first.keys():
            raise ValueError(f"{name} has different parameters from {names[0]}: not the same network.")
        for key, tensor in first.items():
            if state[key].shape != tensor.shape:
                raise ValueError(f"{name}: {key} has shape {tuple(state[key].shape)}, {names[0]} has "
                                 f"{tuple(tensor.shape)}: not the same network.")
    w = torch.full((len(dicts),), 1.0 / len(dicts)) if weights is None else torch.tensor(weights)
    per_key = {key: expert_weights if expert_weights is not None and key.startswith(EXPERTS) else w for key in first}
    averaged = {key: mean_of([d[key] for d in dicts], per_key[key]) if value.is_floating_point() else dicts[-1][key]
                for key, value in dicts[-1].items()}
    for key in averaged:  # rsl-rl's EmpiricalNormalization keeps _var and _std = sqrt(_var) side by side
        if key.endswith("_std") and key[: -len("_std")] + "_var" in averaged:
            averaged[key] = averaged[key[: -len("_std")] + "_var"].sqrt()
    return averaged


def mean_of(tensors: list[torch.Tensor], weights: torch.Tensor) -> torch.Tensor:
    """The sum of ``tensors`` times ``weights``: one per tensor, summing to 1, or [tensor, expert] for tensors whose
    first dimension is the expert."""
    stacked = torch.stack(tensors)
    return (weights.to(stacked.dtype).view(*weights.shape, *([1] * (stacked.dim() - weights.dim()))) * stacked).sum(0)


def run_and_file(path: str) -> str:
    """'RUN/model_N.pt' without the folders above the run's, which mean nothing where the file is shipped to."""
    return os.path.join(os.path.basename(os.path.dirname(os.path.abspath(path))), os.path.basename(path))


def checked_weights(weights: list[float] | None, count: int) -> list[float] | None:
    """``weights`` scaled to sum to 1; ValueError unless there is one non-negative weight per checkpoint."""
    if weights is None:
        return None
    if len(weights) != count:
        raise ValueError(f"--weights: give one weight per checkpoint: {len(weights)} weights for {count} "
                         "checkpoints.")
    if any(w < 0 for w in weights) or sum(weights) <= 0:
        raise ValueError(f"--weights must be >= 0 and not all 0 (got {weights}).")
    return [w / sum(weights) for w in weights]


def expert_shares(saved: dict, paths: list[str], shares: list[float]) -> torch.Tensor:
    """[checkpoint, expert] weights for two checkpoints, ``shares`` being the second's share in each expert;
    ValueError unless the actor has experts, one share each, in [0, 1]."""
    if len(paths) != 2:
        raise ValueError(f"--expert-weights mixes two checkpoints, not {len(paths)}.")
    experts = [t for k, t in saved["actor_state_dict"].items() if k.startswith(EXPERTS)]
    if not experts:
        raise ValueError(f"{paths[0]}'s actor has no experts ({EXPERTS}*): --expert-weights is for mixture actors.")
    if len(shares) != experts[0].shape[0] or not all(0 <= w <= 1 for w in shares):
        raise ValueError(f"--expert-weights: give one share in [0, 1] per expert: {len(shares)} for "
                         f"{experts[0].shape[0]} experts (got {shares}).")
    second = torch.tensor(shares, dtype=torch.float64)
    return torch.stack([1 - second, second])


def average_checkpoints(paths: list[str], weights: list[float] | None = None, actor_only: bool = False,
                        expert_weights: list[float] | None = None) -> dict:
    """The averaged checkpoint (a dict to save) of ``paths``, in any order: they are sorted by iteration."""
    if len(paths) < 2:
        raise ValueError(f"give at least two checkpoints to average (got {len(paths)}).")
    weights = checked_weights(weights, len(paths))
    saved = [load_checkpoint(path) for path in paths]
    per_expert = None if expert_weights is None else expert_shares(saved[0], paths, expert_weights)
    order = sorted(range(len(paths)), key=lambda i: saved[i].get("iter", 0))
    saved, paths = [saved[i] for i in order], [paths[i] for i in order]
    weights = None if weights is None else [weights[i] for i in order]
    per_expert = None if per_expert is None else per_expert[order]
    actor_only = actor_only or per_expert is not None
    tasks = {s.get("config", {}).get("task") for s in saved}
    if len(tasks) != 1:
        raise ValueError(f"The checkpoints come from different tasks ({', '.join(sorted(map(str, tasks)))}).")
    averaged = {key: value for key, value in saved[-1].items() if key != "optimizer_state_dict"}
    for key in AVERAGED[:1] if actor_only else AVERAGED:
        if all(key in s for s in saved):
            averaged[key] = average_state_dicts([s[key] for s in saved], paths, weights, per_expert)
    averaged["averaged_from"] = [f"{run_and_file(path)}@{s.get('iter')}" for path, s in zip(paths, saved)]
    if weights is not None:
        averaged["averaged_weights"] = weights
    if per_expert is not None:
        averaged["averaged_expert_weights"] = per_expert.tolist()
    return averaged
