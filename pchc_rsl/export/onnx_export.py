"""ONNX export of a preference-conditioned policy with two named inputs, checked against onnxruntime.

rsl-rl's own exporter fixes the batch at 1 and has a single input; a deployed PCHC policy is steered through its
``preference`` input, so it gets its own input with a dynamic batch. The weights are stored inside the .onnx file
(a robot gets one file to copy), which ONNX allows up to 2 GB: far more than any policy here.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import warnings

import numpy as np
import torch

from pchc_rsl.export.metadata import METADATA_KEY
from pchc_rsl.export.onnx_policy import OnnxPolicy
from pchc_rsl.utils.files import atomic_write
from pchc_rsl.utils.finite import first_non_finite_module_tensor

OPSET = 18


def export_onnx(
    policy: torch.nn.Module, path: str, check: bool = True, atol: float = 1e-5, verbose: bool = False,
    metadata: dict | None = None,
) -> str:
    """Export ``policy.as_onnx()`` to ``path`` with inputs ``obs`` [B, obs_dim], ``preference`` [B, m] and output
    ``actions`` [B, A], B dynamic, as one self-contained file. With ``check``, onnxruntime must match torch within
    ``atol`` at B = 1 and 64. Refuses a policy with NaN or inf weights (a diverged training run)."""
    module = policy.as_onnx(verbose=False).to("cpu").eval()
    if list(getattr(module, "input_names", [])) != ["obs", "preference"]:
        raise TypeError(
            f"{type(policy).__name__} does not export a (obs, preference) policy; use a model from pchc_rsl.modules."
        )
    bad = first_non_finite_module_tensor(module)
    if bad is not None:
        raise ValueError(
            f"The policy's '{bad}' holds NaN or inf (training diverged); export a checkpoint from before that."
        )
    batch = {0: torch.export.Dim("batch")}
    with _quiet(verbose), torch.no_grad():
        program = torch.onnx.export(
            module,
            module.get_dummy_inputs(),
            input_names=["obs", "preference"],
            output_names=["actions"],
            dynamic_shapes={"obs": batch, "preference": batch},
            opset_version=OPSET,
            dynamo=True,
            verbose=verbose,
        )
    atomic_write(path, lambda tmp: program.save(tmp, external_data=False))
    if metadata is not None:
        _write_metadata(path, metadata)
    if check:
        check_onnx_against_torch(module, path, atol)
    return path


def _write_metadata(path: str, metadata: dict) -> None:
    """Store ``metadata`` (JSON) in the ONNX file's metadata_props, where onnxruntime exposes it to a deploy."""
    import onnx  # half a second, which every command importing the runner would pay at start

    model = onnx.load(path)
    del model.metadata_props[:]
    entry = model.metadata_props.add()
    entry.key, entry.value = METADATA_KEY, json.dumps(metadata)
    atomic_write(path, lambda tmp: onnx.save(model, tmp))


@contextlib.contextmanager
def _quiet(verbose: bool):
    """Silence torch.onnx's progress prints, log records and warnings unless ``verbose``."""
    if verbose:
        yield
        return
    torch_logger = logging.getLogger("torch.onnx")
    level = torch_logger.level
    torch_logger.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("ignore")
            yield
    finally:
        torch_logger.setLevel(level)


def check_onnx_against_torch(module: torch.nn.Module, path: str, atol: float = 1e-5, seed: int = 0) -> float:
    """Largest |onnxruntime - torch| over random inputs at batch 1 and 64; raises if above ``atol`` or not finite."""
    session = OnnxPolicy(path)
    generator = torch.Generator().manual_seed(seed)
    worst = 0.0
    for batch in (1, 64):
        obs = torch.randn(batch, session.obs_dim, generator=generator)
        lam = torch.rand(batch, session.num_objectives, generator=generator)
        lam = lam / lam.sum(-1, keepdim=True)
        with torch.no_grad():
            expected = module(obs, lam).numpy()
        worst = max(worst, float(np.abs(session(obs.numpy(), lam.numpy()) - expected).max()))
    if not worst <= atol:  # also catches NaN, which compares false with everything
        raise RuntimeError(f"ONNX export of {path} differs from torch by {worst:.3g} > {atol}.")
    return worst
