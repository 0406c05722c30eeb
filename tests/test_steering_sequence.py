import math

import pytest

from tool_loader import load_tool


def test_commands_integrate_to_the_pose_they_describe():
    """0.5 m/s at 0.5 rad/s for pi s is a quarter circle of radius 1: from the origin facing +x it ends at (1, 1)
    facing +y; a side step of 0.3 m/s for 2 s facing +y then moves the robot 0.6 m towards -x."""
    steering = load_tool("diagnostics/steering_sequence")
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
    steering = load_tool("diagnostics/steering_sequence")
    ahead, left = steering.phase_offset((0.0, 0.0), math.pi / 2, (0.1, 0.8), ("forward", 2.0, (0.5, 0.0, 0.0)))
    assert (ahead, left) == pytest.approx((-0.2, -0.1), abs=1e-9)
    ahead, left = steering.phase_offset((1.0, 2.0), 0.0, (1.0, 2.3), ("turn", 3.0, (0.0, 0.0, 0.5)))
    assert (ahead, left) == pytest.approx((0.0, 0.3), abs=1e-9)


def test_a_deploy_command_sequence_file_becomes_one_phase_per_row(tmp_path):
    """pchc-deploy's format: rows at 0, 3 and 9 s held until the next (3 s, 6 s) and the last until --seconds (12 s:
    3 s); checked against the ranges as the deploy checks them."""
    steering = load_tool("diagnostics/steering_sequence")
    ranges = {"lin_vel_x": (-0.5, 1.0), "lin_vel_y": (-0.5, 0.5), "ang_vel_z": (-1.0, 1.0)}
    path = tmp_path / "walk.txt"
    path.write_text("# seconds forward lateral yaw_rate\n0 0.3 0 0\n3, 0, 0.3, 0\n9 0 0 0  # stand\n")
    phases = steering.sequence_from_file(str(path), ranges, 12.0)
    assert [(seconds, command) for _, seconds, command in phases] == [
        (3.0, (0.3, 0.0, 0.0)), (6.0, (0.0, 0.3, 0.0)), (3.0, (0.0, 0.0, 0.0))]
    assert [seconds for _, seconds, _ in steering.sequence_from_file(str(path), ranges)] == [3.0, 6.0, 3.0]
    with pytest.raises(ValueError, match="after the sequence ends"):
        steering.sequence_from_file(str(path), ranges, 9.0)
    path.write_text("0 0.3 0 0\n3 0 0.8 0\n")
    with pytest.raises(ValueError, match=r"walk.txt:2: .*outside the range"):
        steering.sequence_from_file(str(path), ranges)
