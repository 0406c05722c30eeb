"""Release a trained checkpoint: a small .pt (no optimizer, replay buffer or random streams) and its ONNX export.

    python tools/ship_policy.py logs/g1-walk/model_11999.pt --name g1_walk     # -> policies/g1_walk.pt, .onnx

The released .pt is read by pchc-eval, pchc-play and pchc-export-onnx like any checkpoint, and ``pchc-train
--resume`` continues it with a fresh optimizer. Files above --max-mb (default 10) are refused.
"""

from __future__ import annotations

import argparse
import os

import torch

from pchc_rsl.cli import export_onnx
from pchc_rsl.files import atomic_write
from pchc_rsl.runners.checkpoint import load_checkpoint, release_checkpoint


def main(argv: list[str] | None = None) -> list[str]:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("checkpoint")
    parser.add_argument("--name", required=True, help="file name without suffix, e.g. g1_walk")
    parser.add_argument("--out", default="policies", help="folder (default: policies)")
    parser.add_argument("--max-mb", type=float, default=10.0)
    args = parser.parse_args(argv)
    released = release_checkpoint(load_checkpoint(args.checkpoint))
    os.makedirs(args.out, exist_ok=True)
    pt = os.path.join(args.out, f"{args.name}.pt")
    atomic_write(pt, lambda tmp: torch.save(released, tmp))
    onnx = os.path.join(args.out, f"{args.name}.onnx")
    export_onnx.main([pt, "-o", onnx])
    for path in (pt, onnx):
        size = os.path.getsize(path) / 2**20
        if size > args.max_mb:
            os.remove(path)
            raise SystemExit(f"ship_policy: {path} is {size:.1f} MB, above --max-mb {args.max_mb}; removed.")
        print(f"ship_policy: wrote {path} ({size:.2f} MB)")
    return [pt, onnx]


if __name__ == "__main__":
    main()
