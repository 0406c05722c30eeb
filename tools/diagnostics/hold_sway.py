"""How much the G1 sways in HOLD after its gantry or band lets go, as the deploy's stand-still check reads it.

    python tools/diagnostics/hold_sway.py                                # menagerie's G1, stiff gantry let go at 3 s
    python tools/diagnostics/hold_sway.py --unitree-band 12 --hold-up 6  # on unitree_mujoco's band, let go at 6 s
    python tools/diagnostics/hold_sway.py --unitree-band 12 --hold-up 6 --pd-on-arrival \\
        --scene ~/unitree_mujoco/unitree_robots/g1/scene_29dof.xml

In-process, the deploy's own sequence (zero torque, ramp, HOLD) without a policy, until 7 s after the release.
Prints, 1, 2, 4 and 6 s after the release, the largest gyro norm and tilt rate of the second before (a sway's
amplitude: its instantaneous rate passes through 0 twice a period), the pelvis's distance ahead of the feet, and
when the stand-still check (pchc_rsl/deploy/stand_still.py) first passed.
"""

from __future__ import annotations

import argparse

import numpy as np

from pchc_rsl.deploy.deployment import AutoSequence, Deployment, InProcessRobot
from pchc_rsl.deploy.policy_step import PolicyStep
from pchc_rsl.deploy.simulator import G1Simulator
from pchc_rsl.deploy.stand_still import StandStill, tilt_rate

AFTER_S = (1.0, 2.0, 4.0, 6.0)


def sway(policy_file: str, scene: str | None, unitree_band: int | None, hold_up: float, pd_on_arrival: bool) -> dict:
    """Per 50 Hz tick of HOLD: time, gyro norm, tilt rate, pelvis ahead of the feet (m); and when it stood still."""
    sim = G1Simulator(hold_up_s=hold_up, pd_on_arrival=pd_on_arrival, scene=scene, unitree_band=unitree_band)
    policy = PolicyStep(policy_file)
    robot = InProcessRobot(sim, policy.control_period, 500.0)
    run = Deployment(policy, robot, [1.0 / len(policy.objective_names)] * len(policy.objective_names),
                     auto=AutoSequence(hold_s=np.inf), log=lambda *_: None, wait_still=False)
    feet = [sim.model.body(f"{side}_ankle_roll_link").id for side in ("left", "right")]
    gate, rows, last, still_at = StandStill(), [], None, None
    while sim.time < hold_up + max(AFTER_S) + 1.0:
        run.tick()
        state = sim.state()
        if run.safety.mode.name == "HOLD":
            gravity = state.projected_gravity()
            rate = 0.0 if last is None else tilt_rate(last, gravity, policy.control_period)
            ahead = float(sim.data.qpos[0] - sim.data.xpos[feet, 0].mean())
            rows.append((sim.time, float(np.linalg.norm(state.gyro)), rate, ahead))
            last = gravity
            if gate.update(sim.time, state.gyro, gravity) and still_at is None and sim.time >= hold_up:
                still_at = sim.time
            elif not gate.still:
                still_at = None
        robot.wait_tick()
    return {"rows": np.array(rows), "still_at": still_at}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--policy", default="policies/g1_walk.onnx")
    parser.add_argument("--scene", help="another G1 MJCF in unitree_sdk2's motor order (unitree_mujoco's)")
    parser.add_argument("--unitree-band", type=int, metavar="PRESSES", help="unitree_mujoco's band, lowered so often")
    parser.add_argument("--hold-up", type=float, default=3.0, help="s at which the gantry or band lets go")
    parser.add_argument("--pd-on-arrival", action="store_true", help="unitree_mujoco's torque semantics")
    args = parser.parse_args()
    result = sway(args.policy, args.scene, args.unitree_band, args.hold_up, args.pd_on_arrival)
    rows, release = result["rows"], args.hold_up
    before = rows[rows[:, 0] < release]
    if len(before):
        print(f"HOLD before the release: gyro up to {before[:, 1].max():.3f} rad/s")
    for after in AFTER_S:
        second = rows[(rows[:, 0] > release + after - 1.0 + 1e-9) & (rows[:, 0] <= release + after + 1e-9)]
        print(f"{after:g} s after the release: gyro up to {second[:, 1].max():.3f} rad/s, tilt rate up to "
              f"{second[:, 2].max():.3f}/s in the second before; pelvis {100 * second[-1, 3]:+.1f} cm ahead of the "
              "feet")
    still = result["still_at"]
    print("stands still (stand_still.py) " + (f"{still - release:.2f} s after the release" if still is not None else
                                              "not within the run"))


if __name__ == "__main__":
    main()
