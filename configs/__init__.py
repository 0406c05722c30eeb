"""Task registry: ``pchc-train --task NAME`` looks tasks up here; each entry builds a fresh TaskConfig."""

from __future__ import annotations

import difflib
from collections.abc import Callable

from pchc_rsl.configs.base import (
    ACTOR_CLASSES,
    AlgorithmConfig,
    ModelConfig,
    RunnerConfig,
    TaskConfig,
    select_actor,
)
from pchc_rsl.configs.g1_fall_recovery import g1_fall_recovery_fast_task, g1_fall_recovery_task
from pchc_rsl.configs.g1_walk import g1_walk_fast_task, g1_walk_task
from pchc_rsl.configs.mo_gym import mo_halfcheetah_task, mo_hopper_3obj_task, mo_hopper_task, mo_walker2d_task
from pchc_rsl.configs.toy import toy_task

TASKS: dict[str, Callable[[], TaskConfig]] = {
    "toy": toy_task,
    "g1-walk": g1_walk_task,
    "g1-walk-fast": g1_walk_fast_task,
    "g1-fall-recovery": g1_fall_recovery_task,
    "g1-fall-recovery-fast": g1_fall_recovery_fast_task,
    "mo-hopper-2obj-v5": mo_hopper_task,
    "mo-halfcheetah-v5": mo_halfcheetah_task,
    "mo-walker2d-v5": mo_walker2d_task,
    "mo-hopper-v5": mo_hopper_3obj_task,
}


def task_config(name: str) -> TaskConfig:
    """A fresh config for task ``name``; unknown names list the known ones."""
    if name not in TASKS:
        close = difflib.get_close_matches(str(name), list(TASKS), n=1, cutoff=0.6)
        hint = f" Did you mean '{close[0]}'?" if close else ""
        raise ValueError(f"Unknown task '{name}'.{hint} Known tasks: {', '.join(sorted(TASKS))}.")
    return TASKS[name]()


__all__ = ["ACTOR_CLASSES", "AlgorithmConfig", "ModelConfig", "RunnerConfig", "TASKS", "TaskConfig", "select_actor",
           "task_config"]
