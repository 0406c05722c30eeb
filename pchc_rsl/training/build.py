"""Building an environment and a runner from a TaskConfig, and a TaskConfig from a checkpoint: the one way the CLIs,
the evaluation, the tools and the tests build them."""

from __future__ import annotations

import contextlib
import copy
import glob
import io
import json
import os

import torch

from rsl_rl.utils import resolve_callable

from pchc_rsl.configs import TaskConfig, task_config
from pchc_rsl.configs.base import ACTOR_CLASSES, apply_saved
from pchc_rsl.preference import LEGACY_ROUTING_SCALE
from pchc_rsl.training.moved_modules import with_current_names
from pchc_rsl.runners import PCHCRunner
from pchc_rsl.utils.distributed import bind_local_gpu, world
from pchc_rsl.utils.files import atomic_write


def make_env(cfg: TaskConfig):
    """Instantiate the task's VecEnv on cfg.device with cfg.num_envs and cfg.seed."""
    env_class = resolve_callable(cfg.env_class)
    env = env_class(cfg.env, cfg.num_envs, cfg.device, cfg.seed)
    if cfg.fixed_preference is not None:
        env.set_preference(cfg.fixed_preference)
    return env


def make_runner(cfg: TaskConfig, log_dir: str | None = None, verbose: bool = False,
                config: dict | None = None) -> PCHCRunner:
    """Seed torch, build the env and a PCHCRunner; with a log_dir, write the config there as config.json once both
    were built (a folder that already holds checkpoints is refused). ``config`` (default ``cfg.to_dict()``) is what
    checkpoints carry. Construction prints (the models,
    the observation sets) only with ``verbose``."""
    world_size, rank, _ = world()
    if world_size > 1:  # torchrun: each rank its own envs and seed, on its own GPU; rank 0 alone writes files
        cfg.seed += rank
        cfg.device = bind_local_gpu(cfg.device)  # before the env: its physics may allocate on the GPU
        log_dir = log_dir if rank == 0 else None
    if log_dir is not None and glob.glob(os.path.join(log_dir, "model_*.pt")):
        raise FileExistsError(f"{log_dir} already holds checkpoints of another run; give a new folder.")
    torch.manual_seed(cfg.seed)
    config = config if config is not None else cfg.to_dict()
    with contextlib.nullcontext() if verbose else contextlib.redirect_stdout(io.StringIO()):
        env = make_env(cfg)
        runner = PCHCRunner(env, cfg.runner.to_rsl_rl(), log_dir=log_dir, device=cfg.device, config=config,
                            verbose=verbose)
    if log_dir is not None:
        atomic_write(os.path.join(log_dir, "config.json"), lambda tmp: _write_json(tmp, config))
    return runner


def _write_json(path: str, data: dict) -> None:
    with open(path, "w") as f:
        json.dump(data, f, indent=2)


def restore_config(saved: dict) -> TaskConfig:
    """The TaskConfig a checkpoint was trained with (its saved ``config`` dict), rebuilt on the task's dataclasses:
    env, models, algorithm, runner, num_envs, seed, device and fixed preference. Functions and classes it names
    from modules that have moved since it was saved are named where they are now."""
    saved = with_current_names(saved)
    cfg = task_config(saved["task"])
    apply_saved(cfg.runner, saved["runner"])
    apply_saved(cfg.env, saved["env"])
    for key in ("num_envs", "seed", "device", "fixed_preference"):
        if key in saved:
            setattr(cfg, key, saved[key])
    actor = cfg.runner.actor
    if actor.class_name == ACTOR_CLASSES["pci"] and "routing_scale" not in actor.kwargs:
        actor.kwargs["routing_scale"] = LEGACY_ROUTING_SCALE  # saved before the config named it
    return cfg


def placed(cfg: TaskConfig, device: str) -> TaskConfig:
    """``cfg`` run on ``device``: a policy trained on MuJoCo Warp on a GPU is evaluated, exported and played on a
    CPU with C MuJoCo (the physics backend is a matter of training speed, not part of the task; Warp's CPU device is
    for tests); on a GPU, Warp stays."""
    cfg.device = device
    if getattr(cfg.env, "physics", None) == "warp" and torch.device(device).type != "cuda":
        cfg.env.physics = "mujoco"
    return cfg


def for_running(cfg: TaskConfig) -> TaskConfig:
    """``cfg`` for running a trained policy (evaluating, playing, exporting): without the AMP discriminator, which
    only training uses. A checkpoint names its motion clips by the paths they had where it was trained; without this
    it could not be run anywhere else. A copy: the caller's ``cfg`` keeps its discriminator."""
    cfg = copy.deepcopy(cfg)
    cfg.runner.algorithm.amp_cfg = None
    return cfg


def saved_config(path: str, loaded: dict) -> dict:
    """The resolved config pchc-train stored in a loaded checkpoint, with moved modules named where they are now;
    ValueError naming the file if there is none."""
    config = loaded.get("config") or {}
    if "task" not in config:
        raise ValueError(f"{path} has no saved task config; was it written by pchc-train?")
    return with_current_names(config)
