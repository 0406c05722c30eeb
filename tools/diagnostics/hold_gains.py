"""Does the deploy's HOLD stand in unitree_mujoco's G1 model, with its torque semantics? Pushes included.

    python tools/diagnostics/hold_gains.py --scene ~/unitree_mujoco/unitree_robots/g1/scene_29dof.xml [--timestep 0.002]
    python tools/diagnostics/hold_gains.py --scene ... --legs 300,300,200,400,300,200 --leg-kd 10,10,4,12,4,4

In-process, without DDS, what an operator does in unitree_mujoco's simulate_python: the robot hangs on its elastic
band (stiffness 200, damping 100, from 3 m above the origin), motors off for 0.5 s, the ramp to the default pose in
2 s, HOLD; the band is lowered 0.1 m every 0.2 s from 3.5 s (key 8, 12 presses), let go at 6 s (key 9), then a push
at the torso (0.2 s, along x) at 8 s, and HOLD until 20 s. The torque is unitree_mujoco's: ``kp (q_des - q) + kd
(0 - dq)`` computed when a LowCmd arrives (``--lowcmd-hz``) from ``sensordata``, which MuJoCo evaluated before its last
integration (one physics step old), and held. Legs default to pchc-deploy's standing gains (g1_motors); waist and arms
are always those. Prints, per push, when the pelvis fell below 0.45 m (or "stands") and the lowest pelvis after
the release; and how much the joints chatter while the robot hangs (the largest joint speed's standard deviation).
unitree_mujoco is not a dependency: give its scene file (github.com/unitreerobotics/unitree_mujoco).
"""

from __future__ import annotations

import argparse

import mujoco
import numpy as np

from pchc_rsl.deploy.g1_motors import (MOTOR_DEFAULT_POS, MOTOR_EFFORT_LIMIT, MOTOR_JOINTS, MOTOR_STAND_KD,
                                       MOTOR_STAND_KP)
from pchc_rsl.deploy.robot_io import MotorCommand
from pchc_rsl.deploy.simulator import load_scene

RELEASE_S, PUSH_S, END_S = 6.0, 8.0, 20.0


def hold(scene: str, timestep: float, lowcmd_hz: float, kp: np.ndarray, kd: np.ndarray, push: float) -> dict:
    model = load_scene(scene)
    model.opt.timestep = timestep
    data = mujoco.MjData(model)
    torso = model.body("torso_link").id
    mujoco.mj_forward(model, data)
    start = data.sensordata[:29].copy()
    band_length, next_command, t = 0.0, 0.0, 0.0
    hanging_speeds, fell_at, lowest = [], None, np.inf
    while t < END_S:
        ramp = min(max(t - 0.5, 0.0) / 2.0, 1.0)
        target = start + ramp * (MOTOR_DEFAULT_POS - start)
        command = MotorCommand(q=target, kp=kp, kd=kd) if t >= 0.5 else MotorCommand()  # motors off, then PD
        while next_command <= t + 1e-12:  # the LowCmds that arrived before this physics step
            # clipped to the G1's limits here and to the model's ctrlrange by MuJoCo, as unitree_mujoco's is
            data.ctrl[:] = command.torque(data.sensordata[:29], data.sensordata[29:58], MOTOR_EFFORT_LIMIT)
            next_command += 1.0 / lowcmd_hz
        if 3.5 <= t < RELEASE_S:
            band_length = min(1.2, 0.1 * int((t - 3.5) / 0.2 + 1))
        force = np.zeros(3)
        if t < RELEASE_S:  # unitree_mujoco's ElasticBand.Advance
            delta = np.array([0.0, 0.0, 3.0]) - data.qpos[:3]
            distance = np.linalg.norm(delta)
            direction = delta / distance
            force = (200.0 * (distance - band_length) - 100.0 * data.qvel[:3] @ direction) * direction
        elif PUSH_S <= t < PUSH_S + 0.2:
            force = np.array([push, 0.0, 0.0])
        data.xfrc_applied[torso, :3] = force
        mujoco.mj_step(model, data)
        t += timestep
        if 2.5 <= t < 3.5:
            hanging_speeds.append(data.sensordata[29:58].copy())
        if t >= RELEASE_S:
            lowest = min(lowest, float(data.qpos[2]))
            if fell_at is None and data.qpos[2] < 0.45:
                fell_at = t
    chatter = np.std(hanging_speeds, axis=0)
    return {"fell_at": fell_at, "lowest": lowest, "chatter": float(chatter.max()),
            "chatter_joint": MOTOR_JOINTS[int(np.argmax(chatter))]}


def leg_gains(text: str | None, default: np.ndarray) -> np.ndarray:
    gains = default.copy()
    if text:
        values = [float(v) for v in text.split(",")]
        if len(values) != 6:
            raise SystemExit("leg gains are six values: hip pitch, hip roll, hip yaw, knee, ankle pitch, ankle roll")
        gains[:6] = gains[6:12] = values
    return gains


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", required=True, help="unitree_mujoco's unitree_robots/g1/scene_29dof.xml")
    parser.add_argument("--timestep", type=float, default=0.002, help="their SIMULATE_DT (their default: 0.005)")
    parser.add_argument("--lowcmd-hz", type=float, default=500.0)
    parser.add_argument("--legs", help="leg kp: hip pitch, roll, yaw, knee, ankle pitch, roll (default: the deploy's)")
    parser.add_argument("--leg-kd", help="leg kd, the same six")
    parser.add_argument("--pushes", type=float, nargs="+", default=[0.0, 25.0, -25.0, 40.0, -40.0],
                        help="push forces (N, along x, 0.2 s at the torso) to try")
    args = parser.parse_args()
    kp, kd = leg_gains(args.legs, MOTOR_STAND_KP), leg_gains(args.leg_kd, MOTOR_STAND_KD)
    print(f"physics {1 / args.timestep:.0f} Hz, LowCmd {args.lowcmd_hz:.0f} Hz; legs kp {kp[:6].tolist()} "
          f"kd {kd[:6].tolist()}")
    for push in args.pushes:
        try:
            r = hold(args.scene, args.timestep, args.lowcmd_hz, kp, kd, push)
        except ValueError as error:  # not a G1 in unitree_sdk2's motor order
            raise SystemExit(f"hold_gains: {error}") from None
        outcome = "stands" if r["fell_at"] is None else f"fell at {r['fell_at']:.2f} s"
        print(f"push {push:+6.1f} N: {outcome:>16}, lowest pelvis after the release {r['lowest']:.3f} m; while "
              f"hanging the fastest chatter is {r['chatter_joint']} ({r['chatter']:.2f} rad/s std)", flush=True)


if __name__ == "__main__":
    main()
