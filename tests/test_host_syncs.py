"""Host syncs of the training loop: at most one per env step (the env's own), counted without a GPU.

Every operation that would make a GPU wait for the host (a value read, a shape that depends on the data, a copy
from or to the host) is recorded by ``pchc_rsl.utils.host_reads.HostReads``: first that it catches each kind and
passes their sync-free equivalents, then that a whole rollout makes one per env step.
"""

import collections
import os
from collections import deque

import numpy as np
import pytest
import torch
from tensordict import TensorDict

from pchc_rsl.utils.host_reads import HostReads
from rsl_rl.utils import check_nan
from rsl_rl.utils.logger import Logger


def physics_unrecorded(physics, reads: HostReads) -> None:
    """Calls into the physics run with the recorder paused."""
    for name in ("step", "set_qpos_qvel", "sanitize"):
        method = getattr(physics, name)

        def paused(*args, method=method, **kwargs):
            with reads.paused():
                return method(*args, **kwargs)

        setattr(physics, name, paused)


X = torch.arange(6.0)
MASK = X > 2
SYNCING = {
    "item": lambda: X.sum().item(),
    "python if on a tensor": lambda: 1 if X.sum() > 0 else 0,
    "any() in a condition": lambda: bool(MASK.any()),
    "torch.equal": lambda: torch.equal(X, X),
    "nonzero": lambda: MASK.nonzero(),
    "torch.where with one argument": lambda: torch.where(MASK),
    "boolean mask index": lambda: X[MASK],
    "boolean mask assignment of a tensor": lambda: X.clone().__setitem__(MASK, torch.zeros(3)),
    "masked_select": lambda: X.masked_select(MASK),
    "unique": lambda: torch.unique(X),
    "bincount": lambda: torch.bincount(MASK.long()),
    "repeat_interleave without output_size": lambda: torch.repeat_interleave(X, torch.ones(6, dtype=torch.long)),
    "normal with a tensor std": lambda: torch.normal(X, X + 1),
    "a Normal distribution's sample": lambda: torch.distributions.Normal(X, X + 1, validate_args=False).sample(),
    "linalg's error check": lambda: torch.linalg.inv(torch.eye(2)),
    ".cpu()": lambda: X.cpu(),
    ".numpy()": lambda: X.numpy(),
    ".tolist()": lambda: X.tolist(),
    "a tensor from a list": lambda: torch.tensor([1.0, 2.0]),
    "a tensor from a numpy array": lambda: torch.as_tensor(np.zeros(3)),
    "indexing with a list": lambda: X[[1, 2]],
    "a number made a tensor on a device": lambda: torch.tensor(1.0, device="cpu"),
}
"""Each makes a CUDA device wait for the host once (or copies host data to it with a wait)."""

SYNC_FREE = {
    "torch.where": lambda: torch.where(MASK, X, 0.0),
    "masked_fill": lambda: X.masked_fill(MASK, 0.0),
    "mask assignment of a number (masked_fill_)": lambda: X.clone().__setitem__(MASK, 0.0),
    "long index": lambda: X[MASK.long()],
    "repeat_interleave with output_size": lambda: torch.repeat_interleave(X, torch.ones(6, dtype=torch.long),
                                                                          output_size=6),
    "randn": lambda: X + torch.randn_like(X),
    "a number kept on the host": lambda: X * torch.tensor(2.0),
    "len": lambda: len(X),
}


@pytest.mark.parametrize("name", list(SYNCING))
def test_the_recorder_catches_each_kind_of_host_sync(name):
    with HostReads() as reads:
        SYNCING[name]()
    assert len(reads.reads) == 1, reads.where()
    assert reads.reads[0].where.endswith(f"test_host_syncs.py:{_line_of(name)}")


@pytest.mark.parametrize("name", list(SYNC_FREE))
def test_the_recorder_passes_what_does_not_sync(name):
    with HostReads() as reads:
        SYNC_FREE[name]()
    assert reads.reads == []


def _line_of(name: str) -> int:
    """The line of this file that holds the example named ``name``."""
    with open(__file__) as f:
        return next(i for i, line in enumerate(f, 1) if line.strip().startswith(f'"{name}":'))


def test_the_recorder_sees_rsl_rls_per_step_nan_check():
    """rsl-rl's check_nan reads one flag per observation group, one for the rewards and one for the dones."""
    obs = TensorDict({"policy": torch.zeros(4, 3), "critic": torch.zeros(4, 2)}, batch_size=[4])
    with HostReads() as reads:
        check_nan(obs, torch.zeros(4), torch.zeros(4))
    assert [r.kind for r in reads.reads] == ["value read"] * 4


@pytest.mark.parametrize("task,amp,physics", [("g1-walk-fast", True, "mujoco"), ("g1-fall-recovery", False, "mujoco"),
                                              ("g1-walk-fast", False, "warp")])
def test_a_g1_rollout_syncs_once_per_env_step(tmp_path, task, amp, physics):
    """The env, the runner's rollout, the algorithm's act and process_env_step, AMP and the logger: the one host
    sync per env step is the env's finding of the envs to reset; the NaN check reads once per rollout. C MuJoCo's own
    numpy transfers are left out (a device physics makes none); Warp's physics (its CPU device) is recorded."""
    from test_g1_env import g1_available

    if not g1_available():
        pytest.skip("the G1 model is not available (set MENAGERIE_ROOT)")
    motion_dir = os.environ.get("PCHC_MOTION_DIR")
    if amp and not motion_dir:
        pytest.skip("PCHC_MOTION_DIR is not set")
    if physics == "warp":
        pytest.importorskip("mujoco_warp", reason="the warp extra is not installed")
    from pchc_rsl.configs import task_config
    from pchc_rsl.training.build import make_runner

    cfg = task_config(task)
    cfg.num_envs, cfg.runner.num_steps_per_env, cfg.env.physics = 4, 6, physics
    cfg.env.episode_length_s = 0.1  # episodes end inside the rollout: resets and the logger's book-keeping run
    if amp:
        cfg.runner.algorithm.amp_cfg.motion_files = [os.path.join(motion_dir, "lafan1_walk1_subject1.csv")]
    runner = make_runner(cfg, log_dir=str(tmp_path))
    runner.logger.init_logging_writer()
    obs = runner.rollout(runner.env.get_observations())  # the first: what is made once (index tensors) is made
    runner.alg.storage.clear()
    with HostReads() as reads:
        if physics == "mujoco":
            physics_unrecorded(runner.env.physics, reads)
        runner.rollout(obs)
    where = collections.Counter(reads.where())
    steps = cfg.runner.num_steps_per_env
    per_step = {w: n for w, n in where.items() if n > 1}
    assert len(per_step) == 1 and next(iter(per_step)).startswith("nonzero at g1/env.py"), where
    assert sum(where.values()) <= steps + 2, where  # and once per rollout: the NaN check, the physics report
    assert runner.logger.rewbuffer or runner.logger._finished_steps  # episodes did finish


def test_episode_book_keeping_on_the_device_matches_rsl_rls():
    """The same steps through rsl-rl's Logger and ours leave the same finished-episode rewards and lengths, in the
    same order."""
    from pchc_rsl.runners.iteration_log import IterationLogger

    cfg = {"algorithm": {}, "num_steps_per_env": 8}
    loggers = [cls(log_dir=None, cfg=cfg, env_cfg={}, num_envs=5, is_distributed=False, gpu_world_size=1,
                   gpu_global_rank=0, device="cpu") for cls in (Logger, IterationLogger)]
    for logger in loggers:
        logger.writer = object()  # book-keeping runs only with a writer
    generator = torch.Generator().manual_seed(0)
    for _ in range(40):
        rewards = torch.randn(5, generator=generator)
        dones = torch.rand(5, generator=generator) < 0.3
        for logger in loggers:
            logger.process_env_step(rewards, dones, {})
    theirs, ours = loggers
    ours.flush_finished_episodes()
    assert len(theirs.rewbuffer) > 10
    assert list(ours.lenbuffer) == list(theirs.lenbuffer)
    torch.testing.assert_close(torch.tensor(list(ours.rewbuffer)), torch.tensor(list(theirs.rewbuffer)))
    assert isinstance(ours.rewbuffer, deque) and ours.rewbuffer.maxlen == 100


def test_nan_from_the_env_stops_the_rollout_naming_its_source():
    from pchc_rsl.utils.finite import RolloutNaNCheck

    check = RolloutNaNCheck()
    clean = TensorDict({"policy": torch.zeros(3, 2), "critic": torch.zeros(3, 2)}, batch_size=[3])
    check.add(clean, torch.zeros(3), torch.zeros(3))
    check.raise_if_any()  # nothing: clean steps
    dirty = clean.clone()
    dirty["critic"][1, 0] = float("nan")
    check.add(clean, torch.zeros(3), torch.zeros(3))
    check.add(dirty, torch.zeros(3), torch.zeros(3))
    check.add(clean, torch.zeros(3), torch.zeros(3))
    with pytest.raises(ValueError, match="observation group 'critic'"):
        check.raise_if_any()
