"""tools/diagnostics/velocity_sway.py: the sway of a base whose velocity is a known sine, against numpy's std of it."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from tool_loader import load_tool

velocity_sway = load_tool("diagnostics/velocity_sway")


class SwayingEnv:
    """One env at 0.5 m/s forward with a 0.08 m/s sine sideways at 1 Hz (a step a second), and an average that
    sways by 0.01 m/s at the same rate; dt 0.02."""

    num_envs, dt = 1, 0.02

    def __init__(self):
        self.commands = torch.zeros(1, 3)
        self.robot = SimpleNamespace(base_lin_vel=torch.zeros(1, 3))
        self.command = SimpleNamespace(velocity_average=torch.zeros(1, 3))
        self.t = 0.0

    def set_preference(self, preference):
        pass

    def reset(self):
        self.t = 0.0

    def get_observations(self):
        return None

    def step(self, action):
        self.t += self.dt
        phase = math.sin(2 * math.pi * self.t)
        self.robot.base_lin_vel = torch.tensor([[0.5, 0.08 * phase, 0.0]])
        self.command.velocity_average = torch.tensor([[0.5, 0.01 * phase, 0.0]])
        return None, None, None, None


def test_sway_is_the_std_over_time_of_each_velocity_after_the_settling_time():
    env = SwayingEnv()
    r = velocity_sway.sway(env, lambda obs: None, (0.5, 0.5))
    settle = round(velocity_sway.SETTLE_S / env.dt)
    steps = round((velocity_sway.SETTLE_S + velocity_sway.MEASURE_S) / env.dt)
    t = env.dt * np.arange(settle + 1, steps + 1)
    expected = np.std(np.sin(2 * np.pi * t), ddof=1)  # about 1 / sqrt(2) over whole cycles
    assert float(r["speed"][0]) == pytest.approx(0.5)
    assert float(r["instantaneous"][0, 0]) == pytest.approx(0.0, abs=1e-6)
    assert float(r["instantaneous"][0, 1]) == pytest.approx(0.08 * expected, rel=1e-3)
    assert float(r["averaged"][0, 1]) == pytest.approx(0.01 * expected, rel=1e-3)
