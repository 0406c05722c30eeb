"""Training curves (pchc-runs curves) against env steps and wall-clock hours, across a resumed run's folders."""

import json

import numpy as np
import pytest
from torch.utils.tensorboard import SummaryWriter

from pchc_rsl.cli import runs as runs_cli
from pchc_rsl.evaluation.training_plots import run_curves


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
    steps, hours, values = run_curves(f"{tmp_path / 'a'}+{tmp_path / 'b'}", "Train/mean_reward")
    assert list(values) == list(range(15))
    assert list(steps) == [40 * (i + 1) for i in range(15)]
    np.testing.assert_allclose(hours, [0.1 * (i + 1) for i in range(10)] + [1.0 + 0.2 * (i + 1) for i in range(5)])
    runs_cli.main(["curves", f"{tmp_path / 'a'}+{tmp_path / 'b'}", "--tags", "Train/mean_reward", "--out",
                   str(tmp_path / "c.png")])
    assert (tmp_path / "c.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # a branch resumed from a's iteration 5 while a went on to 9: a@5 keeps a's first 6 iterations only
    fake_run(tmp_path / "branch", range(6, 8), 720.0)
    steps, hours, values = run_curves(f"{tmp_path / 'a'}@5+{tmp_path / 'branch'}", "Train/mean_reward")
    assert list(values) == [0, 1, 2, 3, 4, 5, 6, 7]
    assert list(steps) == [40 * (i + 1) for i in range(8)]
    np.testing.assert_allclose(hours, [0.1 * (i + 1) for i in range(6)] + [0.6 + 0.2, 0.6 + 0.4])
    with pytest.raises(SystemExit, match="^pchc-runs curves: --labels: 1 runs but 2 labels"):
        runs_cli.main(["curves", str(tmp_path / "a"), "--labels", "x", "y"])


def test_iterations_a_resumed_folder_redid_are_counted_once(tmp_path):
    """a logged iterations 0-9, but b was resumed from a's model_7.pt: a's 8 and 9 are not in b's lineage."""
    fake_run(tmp_path / "a", range(0, 10), 360.0)
    fake_run(tmp_path / "b", range(8, 12), 720.0)
    steps, hours, values = run_curves(f"{tmp_path / 'a'}+{tmp_path / 'b'}", "Train/mean_reward")
    assert list(values) == list(range(12))
    assert list(steps) == [40 * (i + 1) for i in range(12)]
    np.testing.assert_allclose(hours, [0.1 * (i + 1) for i in range(8)] + [0.8 + 0.2 * (i + 1) for i in range(4)])


def test_the_printed_table_ends_each_curve_where_the_run_ended(tmp_path, capsys):
    fake_run(tmp_path / "a", range(0, 10), 360.0)
    runs_cli.main(["curves", str(tmp_path / "a"), "--tags", "Train/mean_reward", "Perf/none", "--labels", "run-a",
                   "--out", str(tmp_path / "c.png")])
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].split() == ["run-a", "Train/mean_reward", "7", "400", "1.00"]  # mean of 5..9; 10 x 40 steps
    assert lines[2].split() == ["run-a", "Perf/none", "-"]
    assert lines[3] == f"pchc-runs curves: wrote {tmp_path / 'c.png'}"


def test_a_folder_that_is_not_a_run_or_a_bad_iteration_is_refused_in_one_line(tmp_path):
    fake_run(tmp_path / "a", range(0, 3), 360.0)
    with pytest.raises(SystemExit, match=r"^pchc-runs curves: run .*: .*missing is not a pchc-train run folder"):
        runs_cli.main(["curves", str(tmp_path / "a"), f"{tmp_path / 'a'}+{tmp_path / 'missing'}",
                       "--out", str(tmp_path / "c.png")])
    with pytest.raises(SystemExit, match=r"folder@N, N a whole number"):
        runs_cli.main(["curves", f"{tmp_path / 'a'}@five", "--out", str(tmp_path / "c.png")])
    assert not (tmp_path / "c.png").exists()
