"""The deploy's stand-still check on synthetic IMU traces sampled at the policy's 50 Hz: a decaying sway passes it
at the time worked out by hand below, and a single spike of either signal starts its window again."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pchc_rsl.deploy.stand_still import StandStill, tilt_rate

DT = 0.02


def pitch(t: float, amplitude: float, decay: float, omega: float) -> float:
    """The pitch angle whose rate is amplitude e^(-t / decay) cos(omega t), from 0 at t = 0 (the integral of
    e^(a s) cos(b s) is e^(a s) (a cos(b s) + b sin(b s)) / (a^2 + b^2))."""
    a, b = -1.0 / decay, omega

    def primitive(s):
        return math.exp(a * s) * (a * math.cos(b * s) + b * math.sin(b * s)) / (a * a + b * b)

    return amplitude * (primitive(t) - primitive(0.0))


def gravity_at_pitch(theta: float) -> np.ndarray:
    """Gravity's direction in the frame of a pelvis pitched by ``theta`` about y."""
    return np.array([math.sin(theta), 0.0, -math.cos(theta)])


def first_still(gate: StandStill, times, gyro, gravity) -> float | None:
    for t, w, g in zip(times, gyro, gravity):
        if gate.update(t, w, g):
            return t
    return None


def test_a_decaying_sway_stands_still_one_window_after_its_last_sample_above_the_bounds():
    """Pitch rate 0.2 e^(-t/2) cos(pi t) rad/s (a sway of period 2 s, like the G1's after a band lets go). Above
    0.05 at t = 2.22 s: 0.2 x e^(-1.11) x cos(0.22 pi) = 0.2 x 0.3296 x 0.7705 = 0.0508; below from 2.24 s:
    0.2 x e^(-1.12) x cos(0.24 pi) = 0.2 x 0.3263 x 0.7290 = 0.0476, and the next peak, at 3 s, is 0.2 x e^(-1.5) =
    0.0446. So the window opens at 2.24 s and the robot stands still at 3.24 s. The tilt rate, from the gravity
    of the integrated pitch, crosses between the same samples (its finite difference is the rate mid-step:
    0.0523 at 2.21 s, 0.0492 at 2.23 s)."""
    times = np.round(np.arange(0.0, 6.0, DT), 6)
    rate = [0.2 * math.exp(-t / 2) * math.cos(math.pi * t) for t in times]
    gyro = [np.array([0.0, w, 0.0]) for w in rate]
    gravity = [gravity_at_pitch(pitch(t, 0.2, 2.0, math.pi)) for t in times]
    gate = StandStill(gyro_bound=0.05, tilt_rate_bound=0.05, window_s=1.0)
    assert first_still(gate, times, gyro, gravity) == pytest.approx(3.24)
    assert gate.since == pytest.approx(2.24)
    gate = StandStill(gyro_bound=0.05, tilt_rate_bound=0.05, window_s=1.0)
    for t, w, g in zip(times, gyro, gravity):
        gate.update(t, w, g)
        if abs(t - 2.22) < 1e-9:
            assert gate.gyro == pytest.approx(0.0508, abs=1e-4) and gate.tilt_rate == pytest.approx(0.0523, abs=2e-4)
        if abs(t - 2.24) < 1e-9:
            assert gate.gyro == pytest.approx(0.0476, abs=1e-4) and gate.tilt_rate == pytest.approx(0.0492, abs=2e-4)
            break


def test_a_spike_of_either_signal_starts_the_window_again():
    """A robot at rest (gyro 0.01 rad/s of noise) whose IMU reads one spike of 0.08 rad/s at 0.5 s and whose pelvis
    tilts by 0.002 in one step (0.1/s) at 1.2 s: still from 2.22 s (1 s after the sample following the tilt), not
    from 1.52 s (1 s after the sample following the gyro's spike) nor from 1.0 s (1 s after the start)."""
    gate = StandStill(gyro_bound=0.05, tilt_rate_bound=0.05, window_s=1.0)
    level = np.array([0.0, 0.0, -1.0])
    tilted = np.array([0.002, 0.0, -1.0])
    still = []
    for t in np.round(np.arange(0.0, 3.0, DT), 6):
        gyro = np.array([0.08 if abs(t - 0.5) < 1e-9 else 0.01, 0.0, 0.0])
        gravity = tilted if t >= 1.2 - 1e-9 else level  # one step of tilt between 1.18 s and 1.2 s
        if gate.update(t, gyro, gravity):
            still.append(t)
    assert still == pytest.approx(np.round(np.arange(2.22, 3.0 - 1e-9, DT), 6).tolist())  # and stays still after


def test_a_turn_on_the_spot_is_no_tilt_but_counts_in_the_gyro():
    """The tilt rate leaves the yaw out; the gyro's norm does not."""
    level = np.array([0.0, 0.0, -1.0])
    assert tilt_rate(level, level, DT) == 0.0
    gate = StandStill()
    for t in np.round(np.arange(0.0, 2.0, DT), 6):
        gate.update(t, np.array([0.0, 0.0, 0.1]), level)
    assert not gate.still and gate.tilt_rate == 0.0 and gate.gyro == pytest.approx(0.1)
    assert str(gate).startswith("gyro 0.100 rad/s (bound 0.05), tilt rate 0.000/s (bound 0.05)")
