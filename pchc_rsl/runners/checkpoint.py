"""Reading a checkpoint file with errors that name it: one line saying which file and what is wrong with it."""

from __future__ import annotations

import os
import re
from typing import Any

import torch

_ABSOLUTE_PATH = re.compile(r"(?<![\w.:/~])/(?:[^\s\"',\[\]/]+/)+([^\s\"',\[\]/]+)")


def load_checkpoint(path: str, map_location: str | None = "cpu") -> dict:
    """``torch.load(weights_only=True)`` of a pchc-train checkpoint; ValueError (FileNotFoundError) naming the file
    when it is missing, empty, truncated, not a torch file, or not an rsl-rl checkpoint."""
    if not os.path.isfile(path):
        raise FileNotFoundError(f"No checkpoint at {path}" + (" (a folder)." if os.path.isdir(path) else "."))
    size = os.path.getsize(path)
    if size == 0:
        raise ValueError(f"{path} is empty (0 bytes), not a checkpoint: was its writing interrupted?")
    try:
        loaded = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as error:  # torch raises RuntimeError, EOFError, UnpicklingError, KeyError... for bad files
        reason = (str(error).strip().splitlines() or [""])[0][:160]
        if "zip archive" in reason or "central directory" in reason:  # torch's own text adds nothing here
            raise ValueError(f"{path} ({size} bytes) is truncated or is not a PyTorch checkpoint (not a complete "
                             "zip archive).") from None
        raise ValueError(f"{path} ({size} bytes) is damaged or truncated, or not a PyTorch checkpoint (torch.load "
                         f"failed: {type(error).__name__}: {reason})") from None
    if not isinstance(loaded, dict) or "actor_state_dict" not in loaded:
        raise ValueError(f"{path} is a torch file but not an rsl-rl checkpoint (no actor_state_dict).")
    return loaded


def release_checkpoint(saved: dict) -> dict:
    """A checkpoint for shipping: networks, normalisers, the AMP discriminator, config, iteration and the env's
    progress (the fall-recovery curriculum: assist level and eta's step count), without what only an interrupted run
    needs (optimizer states, the AMP replay buffer, random streams), so that it stays small. pchc-eval, pchc-play
    and pchc-export-onnx read it as any checkpoint; --resume continues it with a fresh optimizer and the curriculum
    where it was. Its config names files without their folders (``without_folders``), so --resume takes the motion
    clips from --motion-files, and it does not keep the actor's ``trained_experts``: which experts the last stage
    fine-tuned belongs to that stage, and a resumed release trains its whole actor, as ``--init-from`` does."""
    dropped = {"optimizer_state_dict", "rnd_optimizer_state_dict", "training_state", "infos"}
    released = {key: value for key, value in saved.items() if key not in dropped}
    if "config" in released:
        released["config"] = without_folders(released["config"])
        actor_kwargs = released["config"].get("runner", {}).get("actor", {}).get("kwargs")
        if actor_kwargs and "trained_experts" in actor_kwargs:
            actor_kwargs.pop("trained_experts")
    if "amp_state_dict" in released:
        released["amp_state_dict"] = {"discriminator": released["amp_state_dict"]["discriminator"]}
    env_state = (saved.get("training_state") or {}).get("env") or {}
    # The env's progress is its scalars (a curriculum level, a step count); its random streams and per-env
    # episode buffers are tensors and dicts, which a fresh run starts anew.
    progress = {key: value for key, value in env_state.items() if isinstance(value, (int, float))}
    if progress:
        released["training_state"] = {"env": progress}
    return released


def without_folders(value: Any) -> Any:
    """``value`` (a config: dicts, lists, strings) with every absolute path in its strings cut to the file's name.
    A config records the paths its run had (motion clips, the checkpoint it resumed or started from); in a released
    file those name folders of the machine it was trained on, which mean nothing where it is used."""
    if isinstance(value, dict):
        return {key: without_folders(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(without_folders(item) for item in value)
    if isinstance(value, str):
        return _ABSOLUTE_PATH.sub(r"\1", value)
    return value
