"""A pchc-train checkpoint exported to ONNX: its policy rebuilt from the config saved inside it, with the env's
deploy metadata, which is what pchc-export-onnx writes."""

from __future__ import annotations

from pchc_rsl.runners import load_checkpoint
from pchc_rsl.training.build import for_running, make_runner, placed, restore_config, saved_config


def export_checkpoint(checkpoint: str, output: str, verbose: bool = False) -> str:
    """Rebuild a pchc-train checkpoint's policy from its saved config (on the CPU, one env) and export it to
    ``output`` with the env's deploy metadata; returns the path written."""
    cfg = placed(restore_config(saved_config(checkpoint, load_checkpoint(checkpoint))), "cpu")
    cfg.num_envs = 1
    if hasattr(cfg.env, "curriculum"):
        cfg.env.curriculum = False  # the deployed action scale is the curriculum's final one, as pchc-eval runs it
    runner = make_runner(for_running(cfg), verbose=verbose)
    runner.load(checkpoint)
    metadata = None
    if hasattr(runner.env, "deploy_metadata"):
        metadata = {"task": cfg.name, **runner.env.deploy_metadata()}
    return runner.export_onnx(output, verbose=verbose, metadata=metadata)
