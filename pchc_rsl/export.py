"""ONNX export of a preference-conditioned policy with two named inputs, and a checked onnxruntime wrapper.

rsl-rl's own exporter fixes the batch at 1 and has a single input; a deployed PCHC policy is steered through its
``preference`` input, so it gets its own input with a dynamic batch. The weights are stored inside the .onnx file
(a robot gets one file to copy), which ONNX allows up to 2 GB: far more than any policy here.
"""

from __future__ import annotations

import contextlib
import io
import logging
import warnings

import numpy as np
import torch

from pchc_rsl.preference import SUM_TOLERANCE, validate_preference
from pchc_rsl.utils.files import atomic_write
from pchc_rsl.utils.finite import first_non_finite_module_tensor

OPSET = 18


METADATA_KEY = "pchc"
"""The ONNX metadata_props key under which the deploy metadata is stored, as JSON."""


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
    import json

    import onnx

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


class OnnxPolicy:
    """An exported policy in onnxruntime: ``actions = policy(obs, preference)`` with the inputs checked up front
    (shapes, a non-empty batch, finite observations, each preference row on the simplex)."""

    def __init__(self, path: str, num_threads: int | None = None) -> None:
        import onnxruntime as ort

        from pchc_rsl.onnx_session import open_onnx_session

        options = ort.SessionOptions()
        if num_threads is not None:
            options.intra_op_num_threads = num_threads
            options.inter_op_num_threads = 1
        self.session = open_onnx_session(path, options)
        inputs = {i.name: i.shape for i in self.session.get_inputs()}
        if set(inputs) != {"obs", "preference"}:
            raise ValueError(f"{path} has inputs {list(inputs)}; a PCHC policy has 'obs' and 'preference'.")
        self.obs_dim = int(inputs["obs"][1])
        self.num_objectives = int(inputs["preference"][1])
        self.path = path
        self._metadata = self.session.get_modelmeta().custom_metadata_map.get(METADATA_KEY)

    @property
    def metadata(self) -> dict:
        """What a deploy needs (task, joints in order, kp, kd, effort limits, default pose, action scale, the
        observation layout, the control period, objectives); ValueError for a file exported without it."""
        if self._metadata is None:
            raise ValueError(f"{self.path} was exported before policies carried their deploy metadata; re-export "
                             f"it: pchc-export-onnx CHECKPOINT.pt -o {self.path} --force")
        import json

        return json.loads(self._metadata)

    def __call__(self, obs: np.ndarray, preference: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float32)
        preference = np.asarray(preference, dtype=np.float32)
        if obs.ndim != 2 or obs.shape[1] != self.obs_dim:
            raise ValueError(f"obs must have shape [B, {self.obs_dim}], got {list(obs.shape)}.")
        if obs.shape[0] == 0:
            raise ValueError(f"obs has no rows (shape {list(obs.shape)}); give at least one observation.")
        if preference.ndim != 2 or preference.shape != (obs.shape[0], self.num_objectives):
            raise ValueError(
                f"preference must have shape [{obs.shape[0]}, {self.num_objectives}] (one row per obs row), "
                f"got {list(preference.shape)}."
            )
        bad_obs = ~np.isfinite(obs)
        if bad_obs.any():
            row, column = (int(i[0]) for i in np.nonzero(bad_obs))
            raise ValueError(
                f"obs row {row} holds {obs[row, column]} at column {column} ({int(bad_obs.any(1).sum())} of "
                f"{obs.shape[0]} rows are not finite); observations must be finite numbers."
            )
        self._check_preference_rows(preference)
        return self.session.run(["actions"], {"obs": obs, "preference": preference})[0]

    def _check_preference_rows(self, preference: np.ndarray) -> None:
        """Raise for the first row off the simplex, naming it (not the whole batch); vectorised for large batches."""
        finite = np.isfinite(preference).all(axis=1)
        sums = np.where(finite, preference.sum(axis=1), np.nan)
        ok = finite & (preference >= 0).all(axis=1) & (np.abs(sums - 1.0) <= SUM_TOLERANCE)
        if not ok.all():
            row = int(np.argmin(ok))
            try:
                validate_preference(preference[row], self.num_objectives)
            except ValueError as error:
                raise ValueError(
                    f"preference row {row} ({int((~ok).sum())} of {preference.shape[0]} rows are bad): {error}"
                ) from None


def export_checkpoint(checkpoint: str, output: str, verbose: bool = False) -> str:
    """Rebuild a pchc-train checkpoint's policy from its saved config (on the CPU, one env) and export it to
    ``output`` with the env's deploy metadata; returns the path written."""
    from pchc_rsl.runners import load_checkpoint
    from pchc_rsl.training.build import make_runner, restore_config, saved_config

    cfg = restore_config(saved_config(checkpoint, load_checkpoint(checkpoint)))
    cfg.num_envs, cfg.device = 1, "cpu"
    if hasattr(cfg.env, "curriculum"):
        cfg.env.curriculum = False  # the deployed action scale is the curriculum's final one, as pchc-eval runs it
    runner = make_runner(cfg, verbose=verbose)
    runner.load(checkpoint)
    metadata = None
    if hasattr(runner.env, "deploy_metadata"):
        metadata = {"task": cfg.name, **runner.env.deploy_metadata()}
    return runner.export_onnx(output, verbose=verbose, metadata=metadata)
