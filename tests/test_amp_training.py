import copy
import os

import numpy as np
import pytest
import torch

from test_g1_env import pytestmark  # noqa: F401  (skip without the G1 model)

from pchc_rsl.configs import task_config
from pchc_rsl.robots.g1.constants import WALK_JOINTS


def write_clip(path, joints, frames=120, fps=30):
    """A 1 Hz sine on every joint, inside the G1's ranges (knees bent 0.2-0.8 rad, ankle rolls within +-0.2)."""
    t = np.arange(frames) / fps
    positions = 0.3 * np.sin(2 * np.pi * 1.0 * t[:, None] + np.arange(len(joints))[None, :])
    positions += np.array([0.5 if "knee" in j else 0.0 for j in joints])
    positions *= np.array([0.6 if "ankle_roll" in j else 1.0 for j in joints])
    root = {"root_positions": np.outer(t, [0.5, 0.0, 0.0]) + [0.0, 0.0, 0.75],  # walking 0.5 m/s along x
            "root_quaternions": np.tile([0.0, 0.0, 0.0, 1.0], (frames, 1))}
    np.savez(path, fps=fps, dof_names=np.array(joints), dof_positions=positions, **root)


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


def test_init_from_with_a_fresh_discriminator_keeps_the_policy_and_not_the_discriminator(tmp_path):
    """--init-from copies the actor and the discriminator; with --fresh-discriminator the actor only (the
    discriminator as the run starts, before it learns, is not the checkpoint's)."""
    from pchc_rsl.cli import train
    from pchc_rsl.runners import PCHCRunner, load_checkpoint

    write_clip(tmp_path / "clip.npz", WALK_JOINTS)
    common = ["--task", "g1-walk-fast", "--num-envs", "2", "--max-iterations", "1",
              "--motion-files", str(tmp_path / "clip.npz"), "runner.num_steps_per_env=4"]
    train.main([*common, "--log-dir", str(tmp_path / "a")])
    source = str(tmp_path / "a" / "model_0.pt")
    saved = load_checkpoint(source)
    at_start = {}
    learn = PCHCRunner.learn

    def look_then_learn(runner, *args, **kwargs):
        at_start["discriminator"] = copy.deepcopy(runner.alg.amp.discriminator.state_dict())
        at_start["actor"] = copy.deepcopy(runner.alg.actor.state_dict())
        return learn(runner, *args, **kwargs)

    def same(a, b):
        return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(PCHCRunner, "learn", look_then_learn)
        train.main([*common, "--log-dir", str(tmp_path / "b"), "--init-from", source])
        assert same(at_start["discriminator"], saved["amp_state_dict"]["discriminator"])
        train.main([*common, "--log-dir", str(tmp_path / "c"), "--init-from", source, "--fresh-discriminator"])
        assert not same(at_start["discriminator"], saved["amp_state_dict"]["discriminator"])
        assert same(at_start["actor"], saved["actor_state_dict"])
    with pytest.raises(SystemExit, match="--fresh-discriminator applies to --init-from"):
        train.main([*common, "--log-dir", str(tmp_path / "d"), "--fresh-discriminator"])


def test_a_discriminator_of_another_input_width_asks_for_a_fresh_one(tmp_path):
    """A checkpoint whose discriminator read joint angles only, continued with the root velocity in the amp frames:
    one line naming --fresh-discriminator; with it the run trains."""
    from pchc_rsl.cli import train

    write_clip(tmp_path / "clip.npz", WALK_JOINTS)
    common = ["--task", "g1-walk-fast", "--num-envs", "2", "--max-iterations", "1",
              "--motion-files", str(tmp_path / "clip.npz"), "runner.num_steps_per_env=4"]
    train.main([*common, "--log-dir", str(tmp_path / "a")])
    source = str(tmp_path / "a" / "model_0.pt")
    wider = [*common, "env.amp_root_velocity=true", "--init-from", source]
    with pytest.raises(SystemExit, match=r"reads 100 AMP inputs, this run's 115 .* --fresh-discriminator"):
        train.main([*wider, "--log-dir", str(tmp_path / "b")])
    train.main([*wider, "--log-dir", str(tmp_path / "c"), "--fresh-discriminator"])
    assert (tmp_path / "c" / "model_0.pt").exists()
