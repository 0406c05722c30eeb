import math

import pytest

from tool_loader import load_tool


def test_commands_integrate_to_the_pose_they_describe():
    """0.5 m/s at 0.5 rad/s for pi s is a quarter circle of radius 1: from the origin facing +x it ends at (1, 1)
    facing +y; a side step of 0.3 m/s for 2 s facing +y then moves the robot 0.6 m towards -x."""
    steering = load_tool("steering_sequence")
    quarter = [("arc", math.pi, (0.5, 0.0, 0.5))]
    x, y, yaw = steering.integrate_commands(quarter)
    assert (x, y, yaw) == pytest.approx((1.0, 1.0, math.pi / 2), abs=1e-9)
    x, y, yaw = steering.integrate_commands(quarter + [("side", 2.0, (0.0, 0.3, 0.0))])
    assert (x, y) == pytest.approx((0.4, 1.0), abs=1e-9)
    x, y, _ = steering.integrate_commands([("stand", 3.0, (0.0, 0.0, 0.0))], start_xy=(2.0, -1.0))
    assert (x, y) == (2.0, -1.0)


def test_phase_offset_is_measured_in_the_frame_the_phase_started_in():
    """Facing +y at the origin, 2 s forward at 0.5 m/s ends at (0, 1); ending at (0.1, 0.8) is 0.2 m short and
    0.1 m to the right (the robot's left is -x). Turning on the spot does not move the commanded point."""
    steering = load_tool("steering_sequence")
    ahead, left = steering.phase_offset((0.0, 0.0), math.pi / 2, (0.1, 0.8), ("forward", 2.0, (0.5, 0.0, 0.0)))
    assert (ahead, left) == pytest.approx((-0.2, -0.1), abs=1e-9)
    ahead, left = steering.phase_offset((1.0, 2.0), 0.0, (1.0, 2.3), ("turn", 3.0, (0.0, 0.0, 0.5)))
    assert (ahead, left) == pytest.approx((0.0, 0.3), abs=1e-9)
