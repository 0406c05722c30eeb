"""Release a trained checkpoint: a small .pt (no optimizer, replay buffer or random streams) and its ONNX export.

    python tools/ship_policy.py logs/g1-walk/model_11999.pt --name g1_walk     # -> policies/g1_walk.pt, .onnx

The released .pt is read by pchc-eval, pchc-play and pchc-export-onnx like any checkpoint, and ``pchc-train
--resume`` continues it with a fresh optimizer. Files above --max-mb (default 10) are refused. Both files are
written, or neither: they are made in a scratch folder beside the release and moved in together once both are
checked; a release already there is only replaced with --force.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile

import torch

from pchc_rsl.runners.checkpoint import load_checkpoint, release_checkpoint
from pchc_rsl.training.checkpoint_export import export_checkpoint
from pchc_rsl.utils.files import atomic_write


def main(argv: list[str] | None = None) -> list[str]:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("checkpoint")
    parser.add_argument("--name", required=True, help="file name without suffix, e.g. g1_walk")
    parser.add_argument("--out", default="policies", help="folder (default: policies)")
    parser.add_argument("--max-mb", type=float, default=10.0)
    parser.add_argument("--force", action="store_true", help="replace a release of this name")
    args = parser.parse_args(argv)
    targets = [os.path.join(args.out, f"{args.name}{suffix}") for suffix in (".pt", ".onnx")]
    existing = [path for path in targets if os.path.exists(path)]
    if existing and not args.force:
        raise SystemExit(f"ship_policy: {' and '.join(existing)} exist; give another --name, or --force to "
                         "replace the release.")
    released = release_checkpoint(load_checkpoint(args.checkpoint))
    os.makedirs(args.out, exist_ok=True)
    scratch = tempfile.mkdtemp(prefix=f".{args.name}-", dir=args.out)
    try:
        pt, onnx = (os.path.join(scratch, os.path.basename(path)) for path in targets)
        atomic_write(pt, lambda tmp: torch.save(released, tmp))
        export_checkpoint(pt, onnx)
        print(f"ship_policy: exported {onnx}")
        sizes = [os.path.getsize(path) / 2**20 for path in (pt, onnx)]
        for path, size in zip(targets, sizes):
            if size > args.max_mb:
                raise SystemExit(f"ship_policy: {path} would be {size:.1f} MB, above --max-mb {args.max_mb}; "
                                 "nothing written.")
        for made, path, size in zip((pt, onnx), targets, sizes):
            os.replace(made, path)
            print(f"ship_policy: wrote {path} ({size:.2f} MB)")
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return targets


if __name__ == "__main__":
    main()
