"""A trained checkpoint released as a policy: a small .pt (no optimizer, replay buffer or random streams) and its
ONNX export, side by side in one folder (``policies/`` in this repository).

The released .pt is read by pchc-eval, pchc-play and pchc-export-onnx like any checkpoint, and ``pchc-train
--resume`` continues it with a fresh optimizer. Both files are written, or neither: they are made in a scratch
folder beside the release and moved in together once both are checked against the size limit; a release already
there is only replaced when asked to.
"""

from __future__ import annotations

import os
import shutil
import tempfile

import torch

from pchc_rsl.runners.checkpoint import load_checkpoint, release_checkpoint
from pchc_rsl.training.checkpoint_export import export_checkpoint
from pchc_rsl.utils.files import atomic_write

SUFFIXES = (".pt", ".onnx")


def release_policy(checkpoint: str, name: str, folder: str, max_mb: float,
                   force: bool = False) -> list[tuple[str, float]]:
    """Write ``folder/name.pt`` and ``folder/name.onnx`` from ``checkpoint``; returns (path, size in MB) of each.

    FileExistsError for a release of that name (unless ``force``), ValueError for a file above ``max_mb``: either
    way nothing is written."""
    if not name or os.path.basename(name) != name:
        raise ValueError(f"--name {name!r}: give a file name without folders or suffix, e.g. g1_walk (--out is the "
                         "folder).")
    targets = [os.path.join(folder, f"{name}{suffix}") for suffix in SUFFIXES]
    existing = [path for path in targets if os.path.exists(path)]
    if existing and not force:
        raise FileExistsError(f"{' and '.join(existing)} exist; give another --name, or --force to replace the "
                              "release.")
    released = release_checkpoint(load_checkpoint(checkpoint))
    os.makedirs(folder, exist_ok=True)
    scratch = tempfile.mkdtemp(prefix=f".{name}-", dir=folder)
    try:
        made = [os.path.join(scratch, os.path.basename(path)) for path in targets]
        atomic_write(made[0], lambda tmp: torch.save(released, tmp))
        export_checkpoint(made[0], made[1])
        sizes = [os.path.getsize(path) / 2**20 for path in made]
        for path, size in zip(targets, sizes):
            if size > max_mb:
                raise ValueError(f"{path} would be {size:.1f} MB, above --max-mb {max_mb}; nothing written.")
        for source, path in zip(made, targets):
            os.replace(source, path)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return list(zip(targets, sizes))
