"""Whether a simulated robot kept real time: a run whose physics fell behind the wall clock showed the deploy a
robot slower than a real one (each 50 Hz tick found less than 20 ms of physics), so its result is no sim-to-sim
pass, however well the robot walked. Two measures: the bridge's own (simulated over wall time) and the deploy's
(new LowState readings a second, one per physics step in a simulation that keeps up)."""

from __future__ import annotations

REAL_TIME_BOUND = 0.9
"""The least simulated time per wall-clock second (real-time factor) of a run that counts."""
MIN_SECONDS = 1.0
"""The least time over which the deploy's rate of new readings is judged."""


def fresh_per_second(lowstate: dict) -> float | None:
    """New LowState readings a second (``lowstate``: FreshStates.summary()), None over less than MIN_SECONDS."""
    return lowstate["fresh"] / lowstate["seconds"] if lowstate["seconds"] >= MIN_SECONDS else None


def judged(bridge: dict, lowstate: dict) -> dict:
    """The bridge's report with the deploy's view added: ``fresh_states_per_second`` and ``kept_real_time`` only if
    both the bridge's real-time factor and the new readings the deploy saw (against the physics rate) reach the
    bound."""
    fresh = fresh_per_second(lowstate)
    seen = fresh is None or fresh >= REAL_TIME_BOUND / bridge["timestep"]
    return bridge | {"fresh_states_per_second": None if fresh is None else round(fresh, 1),
                     "kept_real_time": bool(bridge["kept_real_time"] and seen)}


def behind_real_time(report: dict) -> str:
    """One line for a bridge report that fell behind: what happened, why it matters, what to do."""
    # with the torque held from arrival, a slower physics computes it from older sensors: HOLD no longer stands
    slower = (" or simulate at 250 Hz (--timestep 0.004),"
              if report["timestep"] < 0.004 and not report.get("pd_on_arrival") else "")
    rate = 1 / report["timestep"]
    if report["real_time_factor"] >= REAL_TIME_BOUND:
        what = (f"the deploy saw {report['fresh_states_per_second']:.0f} new LowState readings a second from a "
                f"simulation of {rate:.0f} Hz physics (bound {REAL_TIME_BOUND} x {rate:.0f}), although the simulation "
                f"kept {report['real_time_factor']:.2f} of real time: its states reached the deploy late or not at all")
    else:
        what = (f"the simulation fell behind real time: {report['sim_time']:.1f} s simulated in {report['wall_s']:.1f} "
                f"s (real-time factor {report['real_time_factor']:.2f}, bound {REAL_TIME_BOUND}), "
                f"{report['late_share']:.0%} of physics steps late, slowest step {report['slowest_step_ms']:.0f} ms")
    return (f"{what}. This machine is too busy for {rate:.0f} Hz physics in real time, so the run is no sim-to-sim "
            f"result: close other programs,{slower} or use --mujoco (lockstep, no real time needed).")
