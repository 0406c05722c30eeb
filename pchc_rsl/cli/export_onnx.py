"""pchc-export-onnx: export a checkpoint's policy to ONNX with inputs obs and preference."""

from __future__ import annotations

import argparse
import os

from pchc_rsl.runners import load_checkpoint


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="pchc-export-onnx",
        description="Export the deterministic policy of a pchc-train checkpoint to ONNX (inputs 'obs' [B, obs_dim] "
        "and 'preference' [B, m], output 'actions'; dynamic batch) and check it against torch in onnxruntime.",
    )
    parser.add_argument("checkpoint")
    parser.add_argument("-o", "--output", help="ONNX file (default: next to the checkpoint, same name .onnx)")
    args = parser.parse_args(argv)

    from pchc_rsl.cli.common import make_runner
    from pchc_rsl.configs import task_config

    config = load_checkpoint(args.checkpoint).get("config") or {}
    if "task" not in config:
        raise SystemExit(f"pchc-export-onnx: {args.checkpoint} has no saved config; was it written by pchc-train?")
    cfg = task_config(config["task"])
    restore_config(cfg, config)
    cfg.num_envs = 1
    runner = make_runner(cfg)
    runner.load(args.checkpoint)
    output = args.output or os.path.splitext(args.checkpoint)[0] + ".onnx"
    runner.export_onnx(output)
    print(f"pchc-export-onnx: wrote {output}")


def restore_config(cfg, saved: dict) -> None:
    """Apply a checkpoint's saved env and model settings to a fresh TaskConfig, so everything is rebuilt as trained."""
    from pchc_rsl.configs.base import apply_saved

    apply_saved(cfg.runner, saved["runner"])
    apply_saved(cfg.env, saved["env"])


if __name__ == "__main__":
    main()
