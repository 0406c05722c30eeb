import pytest

from pchc_rsl.configs import task_config


@pytest.fixture
def toy_cfg():
    """The toy task, small."""
    cfg = task_config("toy")
    cfg.num_envs = 8
    return cfg
