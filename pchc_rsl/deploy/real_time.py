"""Whether a simulated robot kept real time: a run whose physics fell behind the wall clock showed the deploy a
robot slower than a real one (each 50 Hz tick found less than 20 ms of physics), so its result is no sim-to-sim
pass, however well the robot walked."""

from __future__ import annotations

REAL_TIME_BOUND = 0.9
"""The least simulated time per wall-clock second (real-time factor) of a run that counts."""


def behind_real_time(report: dict) -> str:
    """One line for a bridge report that fell behind: what happened, why it matters, what to do."""
    # with the torque held from arrival, a slower physics computes it from older sensors: HOLD no longer stands
    slower = (" or simulate at 250 Hz (--timestep 0.004),"
              if report["timestep"] < 0.004 and not report.get("pd_on_arrival") else "")
    return (f"the simulation fell behind real time: {report['sim_time']:.1f} s simulated in {report['wall_s']:.1f} s "
            f"(real-time factor {report['real_time_factor']:.2f}, bound {REAL_TIME_BOUND}), {report['late_share']:.0%} "
            f"of physics steps late, slowest step {report['slowest_step_ms']:.0f} ms. This machine is too busy for "
            f"{1 / report['timestep']:.0f} Hz physics in real time, so the run is no sim-to-sim result: close other "
            f"programs,{slower} or use --mujoco (lockstep, no real time needed).")
