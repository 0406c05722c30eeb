"""PCHCRunner: rsl-rl's OnPolicyRunner with self-describing, atomic, weights-only checkpoints and ONNX export."""

from __future__ import annotations

import os
import tempfile

import torch

from rsl_rl.env import VecEnv
from rsl_rl.runners import OnPolicyRunner

from pchc_rsl.export import export_onnx


class PCHCRunner(OnPolicyRunner):
    """OnPolicyRunner whose checkpoints carry the resolved config they were trained with.

    ``config`` is a plain dict (str, numbers, lists, dicts) describing the task, so that a checkpoint can be
    evaluated or exported without guessing its settings, and loaded with ``torch.load(weights_only=True)``.
    """

    def __init__(
        self, env: VecEnv, train_cfg: dict, log_dir: str | None = None, device: str = "cpu", config: dict | None = None
    ) -> None:
        super().__init__(env, train_cfg, log_dir, device)
        self.config = config or {}

    def save(self, path: str, infos: dict | None = None) -> None:
        """Write the checkpoint to a temp file in the same folder, then rename: a crash never leaves half a file."""
        saved = self.alg.save()
        saved["iter"] = self.current_learning_iteration
        saved["infos"] = infos
        saved["config"] = self.config
        directory = os.path.dirname(os.path.abspath(path))
        os.makedirs(directory, exist_ok=True)
        fd, tmp_path = tempfile.mkstemp(dir=directory, suffix=".pt.tmp")
        os.close(fd)
        try:
            torch.save(saved, tmp_path)
            os.replace(tmp_path, path)
        finally:
            if os.path.exists(tmp_path):
                os.remove(tmp_path)
        self.logger.save_model(path, self.current_learning_iteration)

    def load(
        self, path: str, load_cfg: dict | None = None, strict: bool = True, map_location: str | None = None
    ) -> dict | None:
        """Load a checkpoint written by ``save``; refuse one trained for another task."""
        loaded = load_checkpoint(path, map_location)
        theirs, ours = loaded.get("config", {}).get("task"), self.config.get("task")
        if theirs is not None and ours is not None and theirs != ours:
            raise ValueError(f"{path} was trained on task '{theirs}', but this runner is set up for '{ours}'.")
        try:
            load_iteration = self.alg.load(loaded, load_cfg, strict)
        except RuntimeError as error:
            raise ValueError(
                f"{path} does not fit this runner's models (was it trained with another config?): {error}"
            ) from error
        if load_iteration:
            self.current_learning_iteration = loaded["iter"]
        return loaded["infos"]

    def export_onnx(self, path: str) -> str:
        """Export the deterministic policy (inputs ``obs``, ``preference``) and check it against torch."""
        return export_onnx(self.alg.get_policy(), path)


def load_checkpoint(path: str, map_location: str | None = "cpu") -> dict:
    """``torch.load(weights_only=True)`` with an error that names the file when it is not a PCHC checkpoint."""
    if not os.path.isfile(path):
        raise FileNotFoundError(f"No checkpoint at {path}.")
    loaded = torch.load(path, map_location=map_location, weights_only=True)
    if not isinstance(loaded, dict) or "actor_state_dict" not in loaded:
        raise ValueError(f"{path} is not an rsl-rl checkpoint (no actor_state_dict).")
    return loaded
