"""Average the networks of several checkpoints of one run (uniform weight averaging, as in SWA).

    python tools/average_checkpoints.py RUN/model_{350,400,450,500,550}.pt --out avg.pt

Why: late in a run PPO keeps moving the policy, and consecutive checkpoints 50 iterations apart differ by more than
a table's intervals at the ends of the preference range (docs/design.md, "Checkpoint averaging"). The mean of the
actor's (and critics') parameters over a stretch of checkpoints cancels much of that noise. Only checkpoints of one lineage make sense here: averaging works for nearby points of
one training trajectory, not for independently trained networks.

Floating-point tensors of the actor and critic (weights and observation normalisers) and the value normaliser the
critics predict in are averaged; a normaliser's std is then recomputed as sqrt(var) of its averaged variance (the
mean of the stds is not the std of the mean variance). Everything else (config, iteration, AMP discriminator,
curriculum) is the newest checkpoint's. The optimizer state
is dropped, so ``pchc-train --resume`` starts a fresh one, as for a released policy. The file records what it was
averaged from under ``averaged_from`` (run folder, file and iteration of each).
"""

from __future__ import annotations

import argparse
import os

import torch

from pchc_rsl.runners.checkpoint import load_checkpoint
from pchc_rsl.utils.files import atomic_write

AVERAGED = ("actor_state_dict", "critic_state_dict", "value_normalizer_state_dict")


def average_state_dicts(dicts: list[dict], names: list[str]) -> dict:
    """Mean of each floating-point tensor; other entries (sample counts) from the last. Keys and shapes must match."""
    first = dicts[0]
    for state, name in zip(dicts[1:], names[1:]):
        if state.keys() != first.keys():
            raise ValueError(f"{name} has different parameters from {names[0]}: not the same network.")
        for key, tensor in first.items():
            if state[key].shape != tensor.shape:
                raise ValueError(f"{name}: {key} has shape {tuple(state[key].shape)}, {names[0]} has "
                                 f"{tuple(tensor.shape)}: not the same network.")
    averaged = {key: torch.stack([d[key] for d in dicts]).mean(0) if value.is_floating_point() else dicts[-1][key]
                for key, value in dicts[-1].items()}
    for key in averaged:  # rsl-rl's EmpiricalNormalization keeps _var and _std = sqrt(_var) side by side
        if key.endswith("_std") and key[: -len("_std")] + "_var" in averaged:
            averaged[key] = averaged[key[: -len("_std")] + "_var"].sqrt()
    return averaged


def run_and_file(path: str) -> str:
    """'RUN/model_N.pt' without the folders above the run's, which mean nothing where the file is shipped to."""
    return os.path.join(os.path.basename(os.path.dirname(os.path.abspath(path))), os.path.basename(path))


def average_checkpoints(paths: list[str]) -> dict:
    if len(paths) < 2:
        raise ValueError("Give at least two checkpoints to average.")
    saved = [load_checkpoint(path) for path in paths]
    order = sorted(range(len(paths)), key=lambda i: saved[i].get("iter", 0))
    saved, paths = [saved[i] for i in order], [paths[i] for i in order]
    tasks = {s.get("config", {}).get("task") for s in saved}
    if len(tasks) != 1:
        raise ValueError(f"The checkpoints come from different tasks ({', '.join(sorted(map(str, tasks)))}).")
    averaged = {key: value for key, value in saved[-1].items() if key != "optimizer_state_dict"}
    for key in AVERAGED:
        if all(key in s for s in saved):
            averaged[key] = average_state_dicts([s[key] for s in saved], paths)
    averaged["averaged_from"] = [f"{run_and_file(path)}@{s.get('iter')}" for path, s in zip(paths, saved)]
    return averaged


def main(argv: list[str] | None = None) -> str:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("checkpoints", nargs="+")
    parser.add_argument("--out", required=True, help="the averaged checkpoint's path")
    args = parser.parse_args(argv)
    averaged = average_checkpoints(args.checkpoints)
    atomic_write(args.out, lambda tmp: torch.save(averaged, tmp))
    print(f"average_checkpoints: wrote {args.out}, the mean of {len(args.checkpoints)} checkpoints "
          f"(iterations {averaged['averaged_from'][0].rsplit('@', 1)[1]} to {averaged['iter']})")
    return args.out


if __name__ == "__main__":
    main()
