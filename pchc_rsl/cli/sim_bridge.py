"""pchc-sim-bridge: the 29-DoF G1 in MuJoCo behind rt/lowcmd and rt/lowstate, for sim-to-sim before a robot."""

from __future__ import annotations

import argparse
import signal

from pchc_rsl.cli import arguments
from pchc_rsl.cli.simulation_arguments import add_simulation_arguments, check_band_arguments
from pchc_rsl.deploy.real_time import behind_real_time
from pchc_rsl.deploy.sdk import DdsBridgeEnd, SdkMissing
from pchc_rsl.deploy.sim_bridge import SimBridge
from pchc_rsl.deploy.simulator import G1Simulator, SimulationDiverged

PROG = "pchc-sim-bridge"


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
