"""The simulated G1's command-line options, shared by pchc-sim-bridge and pchc-deploy --sim / --mujoco (which must
not load MuJoCo to parse them: on a robot it never simulates)."""

from __future__ import annotations

import argparse

from pchc_rsl.cli import arguments


def non_negative_ms(text: str) -> float:
    value = float(text) if text.replace(".", "", 1).isdigit() else -1.0
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a number of milliseconds >= 0, got '{text}'")
    return value


def band_presses(text: str) -> int:
    value = int(text) if text.isdigit() else -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a whole number of key presses >= 0, got '{text}'")
    return value


def add_simulation_arguments(parser) -> None:
    """Options of the simulated G1 (pchc-sim-bridge; pchc-deploy --sim and --mujoco)."""
    parser.add_argument("--timestep", type=arguments.positive_float, default=0.002,
                        help="physics step in s (default 0.002: 500 Hz, the G1's low-level rate)")
    parser.add_argument("--latency-ms", type=non_negative_ms, default=0.0,
                        help="delay before a received LowCmd takes effect (default 0)")
    parser.add_argument("--jitter-ms", type=non_negative_ms, default=0.0,
                        help="uniform extra delay in [0, J] ms on each LowCmd (default 0)")
    parser.add_argument("--hold-up", type=float, default=3.0, metavar="S",
                        help="hold the pelvis up by an elastic band for the first S seconds, as a gantry does while "
                        "the motors are off and ramping (default 3; 0: none)")
    parser.add_argument("--pd-on-arrival", action="store_true",
                        help="compute each motor's torque once when a LowCmd arrives and hold it until the next, as "
                        "unitree_mujoco's simulate_python does (default: recompute the PD law at every physics step, "
                        "as the G1's motor drivers do); with --latency-ms the torque is computed when the delayed "
                        "command takes effect. Their default physics rate is --timestep 0.005")
    parser.add_argument("--unitree-band", type=band_presses, metavar="PRESSES",
                        help="hang the robot on unitree_mujoco's elastic band instead (200 N/m from 3 m above the "
                        "origin to the torso), lowered by PRESSES presses of their key 8 (0.1 m each, 0.2 s apart) "
                        "before it lets go at --hold-up")
    parser.add_argument("--band-force-stays", action="store_true",
                        help="with --unitree-band: the band's last force stays on the torso after it lets go, as in "
                        "unitree_mujoco's simulate_python loop run without its viewer (the viewer's sync clears it)")
    parser.add_argument("--scene", metavar="MJCF", help="simulate this G1 model instead of mujoco-menagerie's: 29 "
                        "torque motors in unitree_sdk2's order, e.g. unitree_mujoco's "
                        "unitree_robots/g1/scene_29dof.xml (with --pd-on-arrival: their model and torque semantics)")


def check_band_arguments(parser, args) -> None:
    if args.band_force_stays and args.unitree_band is None:
        parser.error("--band-force-stays is about unitree_mujoco's band: give --unitree-band PRESSES too")
