"""Checks of a resolved TaskConfig before any work starts: values in range, a device this torch can use.

Command-line flags are range-checked by their argparse types; these checks cover the same settings when they come
from ``key=value`` overrides or a resumed checkpoint, and the ones without a flag.
"""

from __future__ import annotations

import math

import torch

from pchc_rsl.configs import TaskConfig
from pchc_rsl.envs.physics.backend import BACKENDS

AT_LEAST_ONE = ("num_envs", "runner.max_iterations", "runner.save_interval", "runner.num_steps_per_env",
                "runner.algorithm.num_learning_epochs", "runner.algorithm.num_mini_batches")
POSITIVE = ("runner.algorithm.learning_rate", "runner.algorithm.clip_param", "runner.algorithm.max_grad_norm",
            "runner.algorithm.desired_kl")
UNIT_INTERVAL = ("runner.algorithm.gamma", "runner.algorithm.lam")


def check_task_config(cfg: TaskConfig) -> None:
    """ValueError (one line: the key, its value, what is allowed) for the first setting out of range."""
    for key in AT_LEAST_ONE:
        value = _get(cfg, key)
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{key} must be a whole number >= 1, got {value!r}.")
    for key in POSITIVE:
        value = _get(cfg, key)
        if not _number(value) or not value > 0:
            raise ValueError(f"{key} must be a finite number > 0, got {value!r}.")
    for key in UNIT_INTERVAL:
        value = _get(cfg, key)
        if not _number(value) or not 0 <= value <= 1:
            raise ValueError(f"{key} must be in [0, 1], got {value!r}.")
    for key in ("runner.algorithm.entropy_coef", "runner.algorithm.value_loss_coef"):
        value = _get(cfg, key)
        if not _number(value) or value < 0:
            raise ValueError(f"{key} must be a finite number >= 0, got {value!r}.")
    batch = cfg.num_envs * cfg.runner.num_steps_per_env
    if cfg.runner.algorithm.num_mini_batches > batch:
        raise ValueError(
            f"runner.algorithm.num_mini_batches={cfg.runner.algorithm.num_mini_batches} exceeds the {batch} samples "
            f"of a rollout (num_envs x runner.num_steps_per_env); lower it or raise num_envs."
        )
    check_device(cfg.device)
    check_physics(getattr(cfg.env, "physics", None))


def check_physics(backend: str | None) -> None:
    """ValueError unless the G1 physics backend exists and is installed (None: the task has one physics)."""
    if backend is None:
        return
    if backend not in BACKENDS:
        raise ValueError(f"env.physics must be one of {', '.join(BACKENDS)}, got {backend!r}.")
    if backend == "warp":
        try:
            import mujoco_warp  # noqa: F401
        except ImportError:
            raise ValueError("--physics warp needs MuJoCo Warp, which is not installed: "
                             "pip install -e \".[warp]\".") from None


def check_device(device: str) -> None:
    """ValueError unless this torch build can use ``device`` (e.g. 'cuda:0' on a CPU-only torch)."""
    try:
        parsed = torch.device(device)
    except (RuntimeError, TypeError):
        raise ValueError(f"device '{device}' is not a torch device; use e.g. cpu or cuda:0.") from None
    if parsed.type == "cuda":
        if not torch.cuda.is_available():
            build = "a CPU-only build" if torch.version.cuda is None else f"built for CUDA {torch.version.cuda}"
            raise ValueError(
                f"device '{device}': this torch ({torch.__version__}, {build}) sees no CUDA GPU; use --device cpu"
                + (" or install a CUDA build of torch." if torch.version.cuda is None else ".")
            )
        if parsed.index is not None and parsed.index >= torch.cuda.device_count():
            raise ValueError(f"device '{device}': only {torch.cuda.device_count()} CUDA device(s) visible.")
    elif parsed.type != "cpu":
        raise ValueError(f"device '{device}': pchc-rsl runs on cpu or cuda devices.")


def _get(cfg, key: str):
    value = cfg
    for part in key.split("."):
        value = getattr(value, part)
    return value


def _number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
