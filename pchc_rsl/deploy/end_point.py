"""Where the walker ended against where its commands lead: the commanded body-frame twist (forward, lateral, yaw
rate), piecewise constant, integrated as a unicycle with exact arcs from the pose the policy started at; the pelvis's
end pose expressed in that start frame (x forward, y left, heading counter-clockwise); the distance between the two.
Averaged tracking errors can hide a walker that circles; its end point cannot."""

from __future__ import annotations

import math

import numpy as np


def integrate_twist(pieces, start=(0.0, 0.0, 0.0)) -> tuple[float, float, float]:
    """(x, y, heading) after ``pieces`` [(seconds, (v_x, v_y, w_z))] of body-frame twist from ``start``: for a
    constant twist the heading turns at w_z and the velocity R(heading) (v_x, v_y) is integrated in closed form."""
    x, y, heading = (float(v) for v in start)
    for seconds, (vx, vy, wz) in pieces:
        turned = heading + wz * seconds
        if abs(wz * seconds) < 1e-9:  # straight: R(heading) v t
            s, c = math.sin(heading), math.cos(heading)
            x += (vx * c - vy * s) * seconds
            y += (vx * s + vy * c) * seconds
        else:  # integral of cos and sin of heading + w_z t over the piece
            ds, dc = math.sin(turned) - math.sin(heading), math.cos(turned) - math.cos(heading)
            x += (vx * ds + vy * dc) / wz
            y += (-vx * dc + vy * ds) / wz
        heading = turned
    return x, y, heading


def yaw_of(quat) -> float:
    """Heading (rad) of a w, x, y, z orientation."""
    w, x, y, z = (float(v) for v in quat)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def in_start_frame(start: tuple[float, float, float], end: tuple[float, float, float]) -> tuple[float, float, float]:
    """``end`` (x, y, heading in the world) seen from ``start``: x along the start heading, y to its left, the
    heading change wrapped to (-pi, pi]."""
    dx, dy = end[0] - start[0], end[1] - start[1]
    c, s = math.cos(start[2]), math.sin(start[2])
    return c * dx + s * dy, -s * dx + c * dy, math.remainder(end[2] - start[2], 2 * math.pi)


def pose_at(trace: np.ndarray, t: float) -> tuple[float, float, float]:
    """(x, y, heading) at time ``t`` from a pose trace [T, 4] of (time, x, y, heading), interpolated."""
    trace = np.asarray(trace, float)
    heading = np.unwrap(trace[:, 3])
    return tuple(float(np.interp(t, trace[:, 0], column)) for column in (trace[:, 1], trace[:, 2], heading))


def end_point_report(commanded: tuple[float, float, float], reached: tuple[float, float, float] | None,
                     imu_heading: float | None = None) -> dict:
    """The figures for the report: poses as [x m, y m, heading deg] in the policy's start frame; ``reached`` None
    on a robot, whose position the deploy does not see (its IMU's heading change is given instead)."""
    def shown(pose):
        return [round(pose[0], 3), round(pose[1], 3), round(math.degrees(pose[2]), 1)]

    out = {"commanded": shown(commanded), "reached": None, "off_m": None, "heading_off_deg": None}
    if reached is not None:
        out["reached"] = shown(reached)
        out["off_m"] = round(math.hypot(reached[0] - commanded[0], reached[1] - commanded[1]), 3)
        out["heading_off_deg"] = round(math.degrees(math.remainder(reached[2] - commanded[2], 2 * math.pi)), 1)
    if imu_heading is not None:
        out["imu_heading_deg"] = round(math.degrees(imu_heading), 1)
    return out
