import math

import pytest
import torch

from pchc_rsl.envs.g1.commanded_path import CommandedPath


def test_the_path_of_a_turning_command_is_the_arc_worked_by_hand():
    """0.5 m/s forward and 0.5 rad/s left for 2 s from heading pi/2 runs along a circle of radius 1 m: it ends at
    (sin 1, 1 - cos 1) ahead and to the left in the start frame, i.e. (-(1 - cos 1), sin 1) in the world, heading
    pi/2 + 1. Sideways at 0.3 m/s from heading pi/2 with no turn, 1 s ends 0.3 m along -x."""
    path = CommandedPath(num_envs=2, dt=0.02, device="cpu")
    path.restart(torch.tensor([True, True]), torch.tensor([[1.0, 2.0], [0.0, 0.0]]), torch.full((2,), math.pi / 2))
    commands = torch.tensor([[0.5, 0.0, 0.5], [0.0, 0.3, 0.0]])
    for _ in range(50):
        path.advance(commands)
    torch.testing.assert_close(path.position[1], torch.tensor([-0.3, 0.0]), atol=1e-6, rtol=0)
    for _ in range(50):
        path.advance(commands)
    arc_end = torch.tensor([1.0 - (1 - math.cos(1.0)), 2.0 + math.sin(1.0)])
    torch.testing.assert_close(path.position[0], arc_end, atol=1e-5, rtol=0)
    assert path.yaw[0].item() == pytest.approx(math.pi / 2 + 1.0, abs=1e-6)
    robot = torch.tensor([[1.0, 3.0], [-0.6, 0.1]])
    torch.testing.assert_close(path.error(robot), robot - torch.stack([arc_end, torch.tensor([-0.6, 0.0])]),
                               atol=1e-5, rtol=0)


def test_a_restart_moves_only_the_envs_it_names():
    path = CommandedPath(num_envs=3, dt=0.02, device="cpu")
    path.advance(torch.tensor([[1.0, 0.0, 0.0]]).expand(3, 3))
    path.restart(torch.tensor([False, True, False]), torch.full((3, 2), 5.0), torch.full((3,), 0.7))
    torch.testing.assert_close(path.position, torch.tensor([[0.02, 0.0], [5.0, 5.0], [0.02, 0.0]]))
    torch.testing.assert_close(path.yaw, torch.tensor([0.0, 0.7, 0.0]))

