import math

import pytest
import torch

from pchc_rsl.runners.iteration_log import IterationLogger


class RecordingWriter:
    def __init__(self):
        self.scalars = {}

    def add_scalar(self, key, value, it):
        self.scalars[key] = float(value)


def logger_with(ep_extras):
    cfg = {"num_steps_per_env": 2, "algorithm": {}, "logger": "tensorboard"}
    logger = IterationLogger(log_dir=None, cfg=cfg, env_cfg={}, num_envs=4, is_distributed=False, gpu_world_size=1,
                             gpu_global_rank=0, device="cpu")
    logger.writer = RecordingWriter()
    logger.ep_extras = ep_extras
    return logger


def test_undefined_episode_values_are_left_out_of_the_iteration_means(capsys):
    """The env logs one value per finished episode, NaN where a metric is undefined (no push in that episode): the
    iteration's figure is the mean over the episodes that define it, each episode counted once."""
    nan = math.nan
    logger = logger_with([
        {"Metrics/push_deviation": torch.tensor([0.2, nan, 0.4]),
         "Episode_Termination/fall": torch.tensor([1.0, 0.0, 0.0])},
        {"Metrics/push_deviation": torch.tensor([nan]), "Episode_Termination/fall": torch.tensor([0.0])},
        {"Metrics/push_deviation": torch.tensor([0.9]), "Episode_Termination/fall": torch.tensor([1.0])},
    ])
    logger.log(it=0, start_it=0, total_it=2, collect_time=1.0, learn_time=1.0, loss_dict={}, learning_rate=1e-3,
               action_std=torch.ones(2), rnd_weight=None)
    assert logger.writer.scalars["Metrics/push_deviation"] == pytest.approx((0.2 + 0.4 + 0.9) / 3)
    assert logger.writer.scalars["Episode_Termination/fall"] == pytest.approx(2 / 5)
    assert "falls  40%" in capsys.readouterr().out
