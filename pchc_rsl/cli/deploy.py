"""pchc-deploy: run an exported policy on a Unitree G1 over unitree_sdk2 (real robot), against the MuJoCo DDS
bridge on loopback (--sim), or in-process MuJoCo without DDS (--mujoco); one code path for all three."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
import tempfile

from pchc_rsl.cli import arguments
from pchc_rsl.cli.sim_bridge import add_simulation_arguments

PROG = "pchc-deploy"


def main(argv: list[str] | None = None) -> None:
    from pchc_rsl.deploy.live_controls import KEY_HELP, REMOTE_HELP

    parser = arguments.Parser(
        prog=PROG,
        description="Run a policy exported by pchc-export-onnx on a G1: wait for rt/lowstate -> zero torque -> "
        "ramp to the default pose (2 s) -> hold -> policy -> damping. Joints the policy does not drive are held at "
        "the default pose. The watchdog damps on a stale LowState, a tilt past 53 degrees or a joint outside its "
        f"range. {KEY_HELP}. {REMOTE_HELP}.",
    )
    parser.add_argument("policy", metavar="POLICY.onnx")
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--network", metavar="IFACE", help="the real robot, on this network interface (e.g. eth0)")
    where.add_argument("--sim", action="store_true",
                       help="start pchc-sim-bridge on loopback with a fresh domain id and run the whole sequence "
                       "without keys: zero torque 0.5 s, ramp 2 s, hold 1 s, policy for --seconds, damping")
    where.add_argument("--mujoco", action="store_true",
                       help="in-process MuJoCo, no DDS, in lockstep (as fast as it computes); same sequence as --sim")
    parser.add_argument("--domain", type=int, default=0, help="DDS domain id for --network (default 0, the robot's)")
    parser.add_argument("--preference", type=arguments.preference, metavar="L1,L2", help="lambda to start with "
                        "(default: the middle of the simplex)")
    parser.add_argument("--command", type=float, default=None, metavar="VX",
                        help="walking: forward speed command in m/s (default 0.5 with --sim/--mujoco, 0 on a robot)")
    parser.add_argument("--seconds", type=arguments.positive_float,
                        help="--sim/--mujoco: seconds of policy (default 10); robot: stop after this long")
    parser.add_argument("--report", metavar="FILE.json", help="write the run's report (fell, base distance, "
                        "messages sent and received, loop overruns, the mode changes)")
    add_simulation_arguments(parser)
    parser.add_argument("--sim-viewer", action="store_true", help="--sim: show the bridge's MuJoCo viewer")
    parser.add_argument("--web", type=int, metavar="PORT", help="also serve a browser console on 127.0.0.1:PORT "
                        "(lambda and command sliders, start / policy / damping buttons; the pchc-rsl[web] extra)")
    parser.add_argument("-v", "--verbose", action="store_true", help="tracebacks instead of one-line errors")
    args = parser.parse_args(argv)
    if not os.path.isfile(args.policy):
        parser.error(f"no policy file at {args.policy}")
    if args.report and os.path.isdir(args.report):
        parser.error(f"--report {args.report} is a folder; give a file such as {args.report}/deploy.json")
    if args.web is not None and args.mujoco:
        parser.error("--web steers a deploy that runs in real time: use it with --sim or --network")
    simulated = args.sim or args.mujoco
    seconds = args.seconds if args.seconds is not None or not simulated else 10.0
    command = args.command if args.command is not None else (0.5 if simulated else 0.0)
    try:
        report = deploy(args, seconds, command)
    except KeyboardInterrupt:  # before the loop took over Ctrl-C (which damps, then exits)
        raise SystemExit(f"{PROG}: interrupted before the deploy loop started; nothing was sent") from None
    except Exception as error:  # noqa: BLE001 - every failure is reported in one line unless -v
        if args.verbose:
            raise
        raise SystemExit(f"{PROG}: {str(error).strip().splitlines()[0] if str(error).strip() else error!r}") from None
    if args.report:
        with open(args.report, "w") as f:
            json.dump(report, f, indent=1)
    summary = {k: report[k] for k in ("final_mode", "reason", "policy_seconds", "messages_sent",
                                       "messages_received") if k in report}
    if "fell" in report:
        summary |= {"fell": report["fell"], "base_distance": report["base_distance"]}
    print(f"{PROG}: {json.dumps(summary)}")


def deploy(args, seconds: float | None, command: float) -> dict:
    from pchc_rsl.deploy.deployment import AutoSequence, Deployment, InProcessRobot, WallClockRobot
    from pchc_rsl.deploy.live_controls import KEY_HELP, KeyReader
    from pchc_rsl.deploy.policy_step import PolicyStep
    from pchc_rsl.preference import validate_preference

    policy = PolicyStep(args.policy)
    m = len(policy.objective_names)
    preference = args.preference or [1.0 / m] * m
    validate_preference(preference, m)
    print(f"{PROG}: {policy.task} policy, {len(policy.joints.policy_joints)} of 29 joints driven, objectives "
          f"{', '.join(policy.objective_names)}, {1 / policy.control_period:.0f} Hz", flush=True)
    auto = AutoSequence() if (args.sim or args.mujoco) else None
    if args.mujoco:
        from pchc_rsl.deploy.simulator import G1Simulator

        sim = G1Simulator(timestep=args.timestep, latency_s=args.latency_ms / 1e3, jitter_s=args.jitter_ms / 1e3,
                          hold_up_s=args.hold_up)
        run = Deployment(policy, InProcessRobot(sim, policy.control_period), preference, command, auto)
        run.run(seconds)
        return with_fall(run.report(), sim.fell, sim.driven_distance())

    from pchc_rsl.deploy.sdk import DdsRobot

    bridge, bridge_report = None, None
    if args.sim:
        domain, interface = random.randint(100, 232), "lo"
        bridge_report = os.path.join(tempfile.mkdtemp(prefix="pchc-sim-bridge-"), "bridge.json")
        bridge = subprocess.Popen(
            [sys.executable, "-m", "pchc_rsl.cli.sim_bridge", "--domain", str(domain), "--network", interface,
             "--timestep", str(args.timestep), "--latency-ms", str(args.latency_ms), "--jitter-ms",
             str(args.jitter_ms), "--hold-up", str(args.hold_up), "--report", bridge_report]
            + (["--viewer"] if args.sim_viewer else []))
    else:
        domain, interface = args.domain, args.network
    keys = console = None
    try:
        dds = DdsRobot(domain, interface)
        keys = KeyReader()
        if keys.active:
            print(f"{PROG}: {KEY_HELP}", flush=True)
        inputs = [keys]
        if args.web is not None:
            from pchc_rsl.deploy.web_console import DeployConsole

            console = DeployConsole(policy.objective_names, preference, command if policy.uses_command else None,
                                    port=args.web)
            inputs.append(console)
            print(f"{PROG}: console at {console.url}", flush=True)
        run = Deployment(policy, WallClockRobot(dds, policy.control_period), preference, command, auto, inputs)
        run.run(seconds, no_state_hint=f" on interface {interface}, DDS domain {domain}"
                + ("" if args.sim else "; is the robot on, in debug mode (L2+R2), and on that interface?"),
                no_state_timeout=30.0 if args.sim else 3.0)  # the bridge takes seconds to start on a busy machine
        report = run.report()
        dds.close()
    finally:
        if keys is not None:
            keys.close()
        if console is not None:
            console.close()
        if bridge is not None:
            bridge.terminate()
            try:
                bridge.wait(timeout=10)
            except subprocess.TimeoutExpired:
                bridge.kill()
    if bridge_report is not None and os.path.exists(bridge_report):
        with open(bridge_report) as f:
            sim_report = json.load(f)
        report = with_fall(report, sim_report["fell"], sim_report["base_distance"]) | {"bridge": sim_report}
    return report


def with_fall(report: dict, fell_in_sim: bool, distance: float) -> dict:
    """The simulated robot fell: its pelvis dropped before damping, or the watchdog damped it for a tilt (it was
    falling; the pelvis may reach the ground only after the damping began)."""
    fell = bool(fell_in_sim) or report["reason"].startswith("tilt")
    return report | {"fell": fell, "base_distance": round(float(distance), 4)}


if __name__ == "__main__":
    main()
