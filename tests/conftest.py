import pytest

from pchc_rsl.configs import task_config


@pytest.fixture
def toy_cfg():
    """The toy task, small."""
    cfg = task_config("toy")
    cfg.num_envs = 8
    return cfg


@pytest.fixture(scope="module")
def walk_checkpoint(tmp_path_factory):
    """A one-iteration g1-walk-fast checkpoint (2 envs), shared by a test module."""
    from test_g1_env import g1_available

    if not g1_available():
        pytest.skip("the G1 model is not available (set MENAGERIE_ROOT)")
    from pchc_rsl.cli import train

    log_dir = tmp_path_factory.mktemp("walk")
    train.main(["--task", "g1-walk-fast", "--num-envs", "2", "--max-iterations", "1", "--log-dir", str(log_dir)])
    return str(log_dir / "model_0.pt")
