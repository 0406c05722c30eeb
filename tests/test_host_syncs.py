"""Host syncs of the training loop: at most one per env step (the env's own), counted without a GPU.

Every call that would read a tensor's value on the host (a device-to-host sync on a GPU) is recorded by
``pchc_rsl.utils.host_reads.HostReads``; C MuJoCo's own numpy transfers are left out (a device physics makes none).
"""

import collections
import os
from collections import deque

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


def test_the_recorder_sees_rsl_rls_per_step_nan_check():
    """rsl-rl's check_nan reads one flag per observation group, one for the rewards and one for the dones."""
    obs = TensorDict({"policy": torch.zeros(4, 3), "critic": torch.zeros(4, 2)}, batch_size=[4])
    with HostReads() as reads:
        check_nan(obs, torch.zeros(4), torch.zeros(4))
        torch.zeros(4)[torch.ones(4, dtype=torch.bool)]
    assert [r.function for r in reads.reads] == ["__bool__"] * 4 + ["__getitem__[mask]"]


@pytest.mark.parametrize("amp", [False, True])
def test_a_g1_walking_rollout_reads_the_host_once_per_env_step(tmp_path, amp):
    from test_g1_env import g1_available

    if not g1_available():
        pytest.skip("the G1 model is not available (set MENAGERIE_ROOT)")
    motion_dir = os.environ.get("PCHC_MOTION_DIR")
    if amp and not motion_dir:
        pytest.skip("PCHC_MOTION_DIR is not set")
    from pchc_rsl.configs import task_config
    from pchc_rsl.training.build import make_runner

    cfg = task_config("g1-walk-fast")
    cfg.num_envs, cfg.runner.num_steps_per_env = 4, 6
    cfg.env.episode_length_s = 0.1  # episodes end inside the rollout: resets and the logger's book-keeping run
    if amp:
        cfg.runner.algorithm.amp_cfg.motion_files = [os.path.join(motion_dir, "lafan1_walk1_subject1.csv")]
    runner = make_runner(cfg, log_dir=str(tmp_path))
    runner.logger.init_logging_writer()
    obs = runner.env.get_observations()
    with HostReads() as reads:
        physics_unrecorded(runner.env.physics, reads)
        runner.rollout(obs)
    where = collections.Counter(reads.where())
    steps = cfg.runner.num_steps_per_env
    env_step = [w for w in where if w.startswith("nonzero at envs/g1_env.py")]
    assert len(env_step) == 1 and where[env_step[0]] == steps, where  # the finished envs, once per step
    assert sum(where.values()) <= steps + 1, where  # and the NaN check, once per rollout
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
