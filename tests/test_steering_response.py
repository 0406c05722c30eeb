"""tools/diagnostics/steering_response.py: the measured yaw rate, speed and heading change of a walker with known
motion."""

import math
from types import SimpleNamespace

import pytest
import torch
from tool_loader import load_tool

steering_response = load_tool("diagnostics/steering_response")


class TurningEnv:
    """Two envs whose base turns at exactly half the commanded yaw rate and walks at 0.4 m/s, with dt 0.02."""

    num_envs, dt = 2, 0.02

    def __init__(self):
        self.commands = torch.zeros(2, 3)
        self.robot = SimpleNamespace(yaw=torch.zeros(2), base_lin_vel=torch.tensor([[0.4, 0.0, 0.0]] * 2))

    def set_preference(self, preference):
        self.preference = preference

    def reset(self):
        self.robot.yaw = torch.tensor([3.1, -3.1])  # near the wrap: the turn must be unwrapped

    def get_observations(self):
        return None

    def step(self, action):
        self.robot.yaw = torch.remainder(self.robot.yaw + 0.5 * self.commands[:, 2] * self.dt + math.pi,
                                         2 * math.pi) - math.pi
        return None, None, None, None


def test_response_measures_the_turn_unwrapped_the_speed_and_the_heading_change():
    env = TurningEnv()
    r = steering_response.response(env, lambda obs: None, (0.5, 0.5), (0.5, 0.0, -0.5))
    torch.testing.assert_close(r["yaw_rate"], torch.full((2,), -0.25), atol=1e-4, rtol=0)
    torch.testing.assert_close(r["speed"], torch.full((2,), 0.4))
    assert r["heading_change"] == pytest.approx([0.25 * 7.0 * 180 / math.pi] * 2, rel=1e-4)


def test_sampled_actions_ask_the_policy_for_its_noisy_output_and_the_default_for_its_mean():
    asked = []

    def policy(obs, **kwargs):
        asked.append(kwargs.get("stochastic_output", False))

    steering_response.response(TurningEnv(), policy, (0.5, 0.5), (0.5, 0.0, 0.0), sampled=True)
    assert asked and all(asked)
    asked.clear()
    steering_response.response(TurningEnv(), policy, (0.5, 0.5), (0.5, 0.0, 0.0))
    assert asked and not any(asked)
