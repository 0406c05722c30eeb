import glob
import os

import pytest
import torch

from pchc_rsl.cli import export_onnx as export_cli
from pchc_rsl.cli import train as train_cli
from pchc_rsl.configs import task_config
from pchc_rsl.export.onnx_policy import OnnxPolicy
from pchc_rsl.training.build import make_runner


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    log_dir = tmp_path_factory.mktemp("run")
    train_cli.main(["--task", "toy", "--num-envs", "8", "--max-iterations", "2", "--seed", "3",
                    "--log-dir", str(log_dir)])
    return log_dir


def test_training_writes_checkpoints_config_and_tensorboard_events(trained):
    assert os.path.isfile(trained / "model_1.pt")
    assert os.path.isfile(trained / "config.json")
    assert glob.glob(str(trained / "events.out.tfevents.*"))
    assert not glob.glob(str(trained / "*.tmp"))  # atomic saves leave no temp files
    checkpoint = torch.load(trained / "model_1.pt", weights_only=True)
    assert checkpoint["config"]["task"] == "toy"
    assert checkpoint["config"]["num_envs"] == 8 and checkpoint["config"]["seed"] == 3
    assert checkpoint["iter"] == 1


def test_export_cli_writes_a_working_onnx_policy(trained, tmp_path):
    out = tmp_path / "policy.onnx"
    export_cli.main([str(trained / "model_1.pt"), "-o", str(out)])
    policy = OnnxPolicy(str(out))
    assert policy.num_objectives == 2
    actions = policy(torch.zeros(4, policy.obs_dim).numpy(), torch.full((4, 2), 0.5).numpy())
    assert actions.shape == (4, 2)


def test_unknown_task_lists_the_known_ones(capsys):
    with pytest.raises(SystemExit, match="Known tasks: .*toy"):
        train_cli.main(["--task", "nope"])


def test_a_checkpoint_from_another_config_is_refused(trained):
    cfg = task_config("toy")
    cfg.num_envs = 4
    cfg.runner.actor.hidden_dims = [8]
    with pytest.raises(ValueError, match="does not fit"):
        make_runner(cfg).load(str(trained / "model_1.pt"))


def test_a_checkpoint_from_another_task_is_refused(trained, tmp_path):
    checkpoint = torch.load(trained / "model_1.pt", weights_only=True)
    checkpoint["config"]["task"] = "g1-walk"
    torch.save(checkpoint, tmp_path / "other.pt")
    cfg = task_config("toy")
    cfg.num_envs = 4
    with pytest.raises(ValueError, match="trained on task 'g1-walk'"):
        make_runner(cfg).load(str(tmp_path / "other.pt"))


def test_baseline_flags(tmp_path):
    with pytest.raises(SystemExit, match="give --fixed-preference"):
        train_cli.main(["--task", "toy", "--actor", "no-preference"])
    with pytest.raises(SystemExit, match="sum to 1"):
        train_cli.main(["--task", "toy", "--fixed-preference", "0.5,0.6"])
    train_cli.main(["--task", "toy", "--actor", "no-preference", "--fixed-preference", "0.25,0.75", "--num-envs", "4",
                    "--max-iterations", "1", "--log-dir", str(tmp_path)])
    checkpoint = torch.load(tmp_path / "model_0.pt", weights_only=True)
    assert checkpoint["config"]["fixed_preference"] == [0.25, 0.75]
    assert checkpoint["config"]["runner"]["obs_groups"]["actor"] == ["policy"]
    # the policy never sees lambda: its first layer takes the policy group only
    assert checkpoint["actor_state_dict"]["mlp.0.weight"].shape[1] == 24
