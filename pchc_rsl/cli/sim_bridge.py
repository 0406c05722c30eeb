"""pchc-sim-bridge: the 29-DoF G1 in MuJoCo behind rt/lowcmd and rt/lowstate, for sim-to-sim before a robot."""

from __future__ import annotations

import argparse
import signal

from pchc_rsl.cli import arguments
from pchc_rsl.deploy.real_time import behind_real_time

PROG = "pchc-sim-bridge"


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
    """Options of the simulated G1, shared with pchc-deploy --sim and --mujoco."""
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


def main(argv: list[str] | None = None) -> None:
    parser = arguments.Parser(
        prog=PROG,
        description="Simulate the full 29-DoF Unitree G1 (mujoco-menagerie) behind unitree_sdk2's DDS topics: "
        "subscribes rt/lowcmd (CRC checked, each motor's PD law recomputed from the latest command at every "
        "physics step, or held from its arrival with --pd-on-arrival, torques clipped to the motor limits, "
        "mode 0 = motor off) and publishes rt/lowstate "
        "(tick, IMU, motor states, wireless_remote) at every step. Stop it with Ctrl-C.",
    )
    parser.add_argument("--domain", type=int, default=1, help="DDS domain id (default 1, as unitree_mujoco)")
    parser.add_argument("--network", default="lo", metavar="IFACE", help="network interface (default lo)")
    add_simulation_arguments(parser)
    parser.add_argument("--seconds", type=arguments.positive_float, help="stop after this much wall time")
    parser.add_argument("--seed", type=arguments.seed, default=0, help="seed of the jitter")
    parser.add_argument("--report", metavar="FILE.json", help="write fell, distance and message counts on exit")
    parser.add_argument("--viewer", action="store_true", help="show MuJoCo's viewer (needs a display)")
    parser.add_argument("--parent-pid", type=int, help=argparse.SUPPRESS)  # pchc-deploy --sim: stop with it
    args = parser.parse_args(argv)
    if not 0 <= args.domain <= 232:
        parser.error(f"--domain must be a DDS domain id in [0, 232], got {args.domain}")
    check_band_arguments(parser, args)

    try:
        from pchc_rsl.deploy.sdk import DdsBridgeEnd, SdkMissing
        from pchc_rsl.deploy.sim_bridge import SimBridge
        from pchc_rsl.deploy.simulator import G1Simulator, SimulationDiverged

        sim = G1Simulator(timestep=args.timestep, latency_s=args.latency_ms / 1e3, jitter_s=args.jitter_ms / 1e3,
                          hold_up_s=args.hold_up, seed=args.seed, visual=args.viewer, pd_on_arrival=args.pd_on_arrival,
                          scene=args.scene, unitree_band=args.unitree_band, band_force_stays=args.band_force_stays)
        bridge = SimBridge(sim, lambda on_command: DdsBridgeEnd(args.domain, args.network, on_command),
                           viewer=args.viewer, parent_pid=args.parent_pid)
    except (ValueError, SdkMissing) as error:
        raise SystemExit(f"{PROG}: {error}") from None
    signal.signal(signal.SIGTERM, lambda *_: bridge.stop.set())
    signal.signal(signal.SIGINT, lambda *_: bridge.stop.set())
    print(f"{PROG}: G1 (29 DoF) on DDS domain {args.domain}, interface {args.network}, "
          f"{1 / args.timestep:.0f} Hz physics", flush=True)
    try:
        bridge.run(args.seconds)
    except SimulationDiverged as error:
        print(f"{PROG}: {error}", flush=True)
    finally:
        if args.report:
            bridge.write_report(args.report)
        report = bridge.report()
        print(f"{PROG}: stopped after {report['sim_time']:.1f} s simulated in {report['wall_s']:.1f} s "
              f"(real-time factor {report['real_time_factor']:.2f}); {report['commands_received']} LowCmd received "
              f"({report['commands_bad_crc']} with a bad CRC), {report['states_sent']} LowState sent; "
              f"{report['late_share']:.0%} of steps late, slowest step {report['slowest_step_ms']:.1f} ms", flush=True)
        if not report["kept_real_time"]:
            print(f"{PROG}: {behind_real_time(report)}", flush=True)


if __name__ == "__main__":
    main()
