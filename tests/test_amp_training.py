import os

import numpy as np
import pytest
import torch

from test_g1_env import pytestmark  # noqa: F401  (skip without the G1 model)

from pchc_rsl.configs import task_config
from pchc_rsl.robots.g1.constants import WALK_JOINTS


def write_clip(path, joints, frames=120, fps=30):
    t = np.arange(frames) / fps
    positions = 0.3 * np.sin(2 * np.pi * 1.0 * t[:, None] + np.arange(len(joints))[None, :])
    np.savez(path, fps=fps, dof_names=np.array(joints), dof_positions=positions)


def test_style_reward_joins_the_task_group_and_the_checkpoint(tmp_path, capsys):
    from pchc_rsl.cli import train
    from pchc_rsl.training.build import make_runner

    write_clip(tmp_path / "clip.npz", WALK_JOINTS)
    cfg = task_config("g1-walk-fast")
    cfg.num_envs = 4
    cfg.runner.algorithm.amp_cfg.motion_files = [str(tmp_path)]
    runner = make_runner(cfg)
    alg, env = runner.alg, runner.env
    assert alg.amp is not None and alg.amp.reference.num_windows > 0
    obs = env.get_observations()
    with torch.inference_mode():
        alg.act(obs)
        obs, rewards, dones, extras = env.step(alg.transition.actions)
        expected_style = alg.amp.discriminator.style_reward(obs["amp"], alg.amp.scale)
        alg.process_env_step(obs, rewards, dones, extras)
    stored = alg.storage.rewards[0]
    torch.testing.assert_close(stored[:, 0], extras["reward_groups"][:, 0] + expected_style)
    torch.testing.assert_close(stored[:, 1:], extras["reward_groups"][:, 1:])
    assert ((expected_style >= 0) & (expected_style <= alg.amp.scale)).all()

    train.main(["--task", "g1-walk-fast", "--num-envs", "4", "--max-iterations", "1", "--log-dir",
                str(tmp_path / "run"), "--motion-files", str(tmp_path / "clip.npz")])
    checkpoint = torch.load(tmp_path / "run" / "model_0.pt", weights_only=True)
    assert "discriminator" in checkpoint["amp_state_dict"]


def test_a_checkpoint_runs_where_its_motion_clips_are_not(tmp_path):
    """A checkpoint names its clips by the paths they had where it was trained. Moved to another machine (here: the
    clip deleted), it still evaluates and exports; only training reads the clips."""
    from pchc_rsl.cli import eval as eval_cli
    from pchc_rsl.cli import train
    from pchc_rsl.training.checkpoint_export import export_checkpoint

    clip = tmp_path / "clip.npz"
    write_clip(clip, WALK_JOINTS)
    train.main(["--task", "g1-walk-fast", "--num-envs", "2", "--max-iterations", "1", "--log-dir",
                str(tmp_path / "run"), "--motion-files", str(clip)])
    checkpoint = str(tmp_path / "run" / "model_0.pt")
    assert torch.load(checkpoint, weights_only=True)["config"]["runner"]["algorithm"]["amp_cfg"]["motion_files"]
    clip.unlink()
    eval_cli.main([checkpoint, "--num-envs", "2", "--episode-length", "0.2", "--preferences", "2", "--output",
                   str(tmp_path / "eval")])
    assert (tmp_path / "eval" / "results.json").exists()
    assert os.path.getsize(export_checkpoint(checkpoint, str(tmp_path / "policy.onnx"))) > 0


def test_running_config_leaves_the_training_config_its_discriminator():
    from pchc_rsl.training.build import for_running

    cfg = task_config("g1-walk-fast")
    running = for_running(cfg)
    assert running.runner.algorithm.amp_cfg is None
    assert cfg.runner.algorithm.amp_cfg is not None and cfg.runner.algorithm.amp_cfg.motion_files is not None


def test_training_without_motions_says_amp_is_off(tmp_path, capsys):
    from pchc_rsl.cli import train

    train.main(["--task", "g1-walk-fast", "--num-envs", "2", "--max-iterations", "1", "--log-dir", str(tmp_path)])
    assert "AMP is off" in capsys.readouterr().out
    assert "amp_state_dict" not in torch.load(tmp_path / "model_0.pt", weights_only=True)


def test_real_clips_drive_the_walking_discriminator(tmp_path):
    import os

    motion_dir = os.environ.get("PCHC_MOTION_DIR")
    if not motion_dir:
        pytest.skip("PCHC_MOTION_DIR is not set")
    from pchc_rsl.training.build import make_runner

    cfg = task_config("g1-walk-fast")
    cfg.num_envs = 2
    cfg.runner.algorithm.amp_cfg.motion_files = [os.path.join(motion_dir, "lafan1_walk1_subject1.csv")]
    runner = make_runner(cfg)
    assert runner.alg.amp.reference.sample(3).shape == (3, 5 * 20)
