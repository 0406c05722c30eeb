"""tools/diagnostics/style_score.py: the style reward it reports is Peng et al.'s c max(0, 1 - (D - 1)^2 / 4) of the
discriminator's score, and a checkpoint without AMP is refused in one line."""

import sys

import pytest
import torch
from test_amp_training import write_clip
from test_g1_env import pytestmark  # noqa: F401  (skip without the G1 model)
from tool_loader import load_tool

from pchc_rsl.robots.g1.constants import WALK_JOINTS

style_score = load_tool("diagnostics/style_score")


def test_style_reward_is_the_clipped_square_of_the_score(tmp_path):
    from pchc_rsl.configs import task_config
    from pchc_rsl.training.build import make_runner

    write_clip(tmp_path / "clip.npz", WALK_JOINTS)
    cfg = task_config("g1-walk-fast")
    cfg.num_envs = 2
    cfg.runner.algorithm.amp_cfg.motion_files = [str(tmp_path / "clip.npz")]
    style = make_runner(cfg).alg.amp
    width = style.reference.sample(1).shape[-1]
    generator = torch.Generator().manual_seed(0)
    windows = torch.cat([style.reference.sample(64), 100.0 * torch.randn(256, width, generator=generator)])
    with torch.no_grad():
        score = style.discriminator(windows).squeeze(-1)
    by_hand = [style.scale * max(0.0, 1.0 - (d - 1.0) ** 2 / 4.0) for d in score.tolist()]
    assert 0 < by_hand.count(0.0) < len(by_hand)  # the clip at 0 is exercised, and so is the square
    mean_score, mean_reward = style_score.style_of(style, windows)
    assert mean_score == pytest.approx(float(score.mean()), abs=1e-6)
    assert mean_reward == pytest.approx(sum(by_hand) / len(by_hand), abs=1e-7)


def test_a_checkpoint_without_amp_is_refused_in_one_line(tmp_path, monkeypatch):
    from pchc_rsl.cli import train

    train.main(["--task", "g1-walk-fast", "--num-envs", "2", "--max-iterations", "1", "--log-dir", str(tmp_path)])
    monkeypatch.setattr(sys, "argv", ["style_score.py", str(tmp_path / "model_0.pt")])
    with pytest.raises(SystemExit, match="trained without AMP"):
        style_score.main()
