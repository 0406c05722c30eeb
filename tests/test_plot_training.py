"""tools/plot_training.py reads curves against env steps and wall-clock hours, across a resumed run's folders."""

import json

import numpy as np
import pytest
from torch.utils.tensorboard import SummaryWriter
from tool_loader import load_tool


def fake_run(folder, iterations, seconds_per_iteration, num_envs=4, steps_per_env=10):
    folder.mkdir()
    (folder / "config.json").write_text(json.dumps({"num_envs": num_envs, "runner": {"num_steps_per_env": steps_per_env}}))
    writer = SummaryWriter(str(folder))
    for it in iterations:
        writer.add_scalar("Train/mean_reward", float(it), it)
        writer.add_scalar("Perf/collection_time", seconds_per_iteration / 2, it)
        writer.add_scalar("Perf/learning_time", seconds_per_iteration / 2, it)
    writer.close()


def test_curves_continue_steps_and_clock_across_a_resume(tmp_path):
    fake_run(tmp_path / "a", range(0, 10), 360.0)  # 10 iterations of 0.1 h, 40 env steps each
    fake_run(tmp_path / "b", range(10, 15), 720.0)  # resumed: 5 more of 0.2 h
    steps, hours, values = load_tool("plot_training").run_curves(f"{tmp_path / 'a'}+{tmp_path / 'b'}", "Train/mean_reward")
    assert list(values) == list(range(15))
    assert list(steps) == [40 * (i + 1) for i in range(15)]
    np.testing.assert_allclose(hours, [0.1 * (i + 1) for i in range(10)] + [1.0 + 0.2 * (i + 1) for i in range(5)])
    load_tool("plot_training").main([f"{tmp_path / 'a'}+{tmp_path / 'b'}", "--tags", "Train/mean_reward", "--out",
                      str(tmp_path / "c.png")])
    assert (tmp_path / "c.png").stat().st_size > 0
    # a branch resumed from a's iteration 5 while a went on to 9: a@5 keeps a's first 6 iterations only
    fake_run(tmp_path / "branch", range(6, 8), 720.0)
    steps, hours, values = load_tool("plot_training").run_curves(f"{tmp_path / 'a'}@5+{tmp_path / 'branch'}",
                                                                 "Train/mean_reward")
    assert list(values) == [0, 1, 2, 3, 4, 5, 6, 7]
    assert list(steps) == [40 * (i + 1) for i in range(8)]
    np.testing.assert_allclose(hours, [0.1 * (i + 1) for i in range(6)] + [0.6 + 0.2, 0.6 + 0.4])
    with pytest.raises(SystemExit, match="labels"):
        load_tool("plot_training").main([str(tmp_path / "a"), "--labels", "x", "y"])


def test_iterations_a_resumed_folder_redid_are_counted_once(tmp_path):
    """a logged iterations 0-9, but b was resumed from a's model_7.pt: a's 8 and 9 are not in b's lineage."""
    fake_run(tmp_path / "a", range(0, 10), 360.0)
    fake_run(tmp_path / "b", range(8, 12), 720.0)
    steps, hours, values = load_tool("plot_training").run_curves(f"{tmp_path / 'a'}+{tmp_path / 'b'}",
                                                                 "Train/mean_reward")
    assert list(values) == list(range(12))
    assert list(steps) == [40 * (i + 1) for i in range(12)]
    np.testing.assert_allclose(hours, [0.1 * (i + 1) for i in range(8)] + [0.8 + 0.2 * (i + 1) for i in range(4)])
