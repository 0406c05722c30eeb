"""ONNX export of a preference-conditioned policy with two named inputs, and a checked onnxruntime wrapper.

rsl-rl's own exporter fixes the batch at 1 and has a single input; a deployed PCHC policy is steered through its
``preference`` input, so it gets its own input with a dynamic batch.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np
import torch

from pchc_rsl.preference import validate_preference

OPSET = 18


def export_onnx(policy: torch.nn.Module, path: str, check: bool = True, atol: float = 1e-5) -> str:
    """Export ``policy.as_onnx()`` to ``path`` with inputs ``obs`` [B, obs_dim], ``preference`` [B, m] and output
    ``actions`` [B, A], B dynamic. With ``check``, onnxruntime must match torch within ``atol`` at B = 1 and 64."""
    module = policy.as_onnx(verbose=False).to("cpu").eval()
    if list(getattr(module, "input_names", [])) != ["obs", "preference"]:
        raise TypeError(
            f"{type(policy).__name__} does not export a (obs, preference) policy; use a model from pchc_rsl.modules."
        )
    dummy = module.get_dummy_inputs()
    batch = {0: torch.export.Dim("batch")}
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    with tempfile.NamedTemporaryFile(dir=directory, suffix=".onnx.tmp", delete=False) as tmp:
        tmp_path = tmp.name
    try:
        with torch.no_grad():
            torch.onnx.export(
                module,
                dummy,
                tmp_path,
                input_names=["obs", "preference"],
                output_names=["actions"],
                dynamic_shapes={"obs": batch, "preference": batch},
                opset_version=OPSET,
                dynamo=True,
                verbose=False,
            )
        os.replace(tmp_path, path)
    finally:
        if os.path.exists(tmp_path):
            os.remove(tmp_path)
    if check:
        check_onnx_against_torch(module, path, atol)
    return path


def check_onnx_against_torch(module: torch.nn.Module, path: str, atol: float = 1e-5, seed: int = 0) -> float:
    """Largest |onnxruntime - torch| over random inputs at batch 1 and 64; raises if above ``atol``."""
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
    if worst > atol:
        raise RuntimeError(f"ONNX export of {path} differs from torch by {worst:.3g} > {atol}.")
    return worst


class OnnxPolicy:
    """An exported policy in onnxruntime: ``actions = policy(obs, preference)`` with shapes checked up front."""

    def __init__(self, path: str, num_threads: int | None = None) -> None:
        import onnxruntime as ort

        options = ort.SessionOptions()
        if num_threads is not None:
            options.intra_op_num_threads = num_threads
            options.inter_op_num_threads = 1
        self.session = ort.InferenceSession(path, options, providers=["CPUExecutionProvider"])
        inputs = {i.name: i.shape for i in self.session.get_inputs()}
        if set(inputs) != {"obs", "preference"}:
            raise ValueError(f"{path} has inputs {list(inputs)}; a PCHC policy has 'obs' and 'preference'.")
        self.obs_dim = int(inputs["obs"][1])
        self.num_objectives = int(inputs["preference"][1])

    def __call__(self, obs: np.ndarray, preference: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float32)
        preference = np.asarray(preference, dtype=np.float32)
        if obs.ndim != 2 or obs.shape[1] != self.obs_dim:
            raise ValueError(f"obs must have shape [B, {self.obs_dim}], got {list(obs.shape)}.")
        if preference.ndim != 2 or preference.shape[0] != obs.shape[0]:
            raise ValueError(
                f"preference must have shape [{obs.shape[0]}, {self.num_objectives}] (one row per obs row), "
                f"got {list(preference.shape)}."
            )
        validate_preference(preference, self.num_objectives)
        return self.session.run(["actions"], {"obs": obs, "preference": preference})[0]
