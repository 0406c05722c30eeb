"""Building an environment and a runner from a TaskConfig: shared by the CLIs and the tests."""

from __future__ import annotations

import json
import os

import torch

from rsl_rl.utils import resolve_callable

from pchc_rsl.configs import TaskConfig
from pchc_rsl.runners import PCHCRunner


def make_env(cfg: TaskConfig):
    """Instantiate the task's VecEnv on cfg.device with cfg.num_envs and cfg.seed."""
    env_class = resolve_callable(cfg.env_class)
    env = env_class(cfg.env, cfg.num_envs, cfg.device, cfg.seed)
    if cfg.fixed_preference is not None:
        env.set_preference(cfg.fixed_preference)
    return env


def make_runner(cfg: TaskConfig, log_dir: str | None = None) -> PCHCRunner:
    """Seed torch, build the env and a PCHCRunner; with a log_dir, write the resolved config there as config.json."""
    torch.manual_seed(cfg.seed)
    env = make_env(cfg)
    config = cfg.to_dict()
    if log_dir is not None:
        os.makedirs(log_dir, exist_ok=True)
        with open(os.path.join(log_dir, "config.json"), "w") as f:
            json.dump(config, f, indent=2)
    return PCHCRunner(env, cfg.runner.to_rsl_rl(), log_dir=log_dir, device=cfg.device, config=config)
