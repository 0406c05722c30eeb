"""pchc-deploy: run an exported policy on a Unitree G1 over unitree_sdk2 (real robot), against the MuJoCo DDS
bridge on loopback (--sim), or in-process MuJoCo without DDS (--mujoco); one code path for all three."""

from __future__ import annotations

import argparse
import json
import os
import random
import subprocess
import sys
import tempfile

from pchc_rsl.cli import arguments
from pchc_rsl.cli.simulation_arguments import add_simulation_arguments, check_band_arguments
from pchc_rsl.deploy.command_sequence import read_command_sequence
from pchc_rsl.deploy.live_controls import KEY_HELP, REMOTE_HELP, Command, KeyReader, check_preference, command_ranges_of
from pchc_rsl.deploy.lowcmd_stream import check_lowcmd_rate
from pchc_rsl.deploy.policy_file import read_metadata
from pchc_rsl.deploy.real_time import behind_real_time, judged
from pchc_rsl.deploy.sdk import DdsRobot
from pchc_rsl.deploy.stand_still import GYRO_BOUND, WINDOW_S
from pchc_rsl.deploy.web_console import DeployConsole

PROG = "pchc-deploy"


def command_vector(text: str) -> list[float]:
    """``VX`` or ``VX,VY,WZ``: forward and lateral speed (m/s), yaw rate (rad/s)."""
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in (1, 3):
        raise argparse.ArgumentTypeError(f"must be VX or VX,VY,WZ (forward m/s, lateral m/s, yaw rate rad/s), "
                                         f"got '{text}'")
    return values + [0.0] * (3 - len(values))


def main(argv: list[str] | None = None) -> None:
    parser = arguments.Parser(
        prog=PROG,
        description="Run a policy exported by pchc-export-onnx on a G1: wait for rt/lowstate -> zero torque -> "
        "ramp to the default pose (2 s) -> hold -> policy -> damping. LowCmd goes out at --lowcmd-hz (500) while "
        "the policy runs at its own rate. Joints the policy does not drive are held at the default pose. The "
        "watchdog damps on a stale LowState, a tilt past 53 degrees, a joint outside its range or a collapse (a "
        f"hip pitch, knee or ankle pitch far from its target). {KEY_HELP}. {REMOTE_HELP}. The operator's guide is "
        "docs/deploy.md.",
    )
    parser.add_argument("policy", metavar="POLICY.onnx")
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--network", metavar="IFACE", help="the real robot, on this network interface (e.g. eth0)")
    where.add_argument("--sim", action="store_true",
                       help="start pchc-sim-bridge on loopback and run the whole sequence without keys: zero torque "
                       "0.5 s, ramp 2 s, hold (--hold-seconds), policy for --seconds, damping; exits non-zero when "
                       "the simulation could not keep real time")
    where.add_argument("--mujoco", action="store_true",
                       help="in-process MuJoCo, no DDS, in lockstep (as fast as it computes); same sequence as --sim")
    parser.add_argument("--domain", type=int, default=None,
                        help="DDS domain id (--network: default 0, the robot's; --sim: default a random one)")
    parser.add_argument("--lowcmd-hz", type=arguments.positive_float, default=500.0, metavar="HZ",
                        help="rate at which LowCmd is written, each message the newest targets and gains with its CRC "
                        "(default 500, the G1's low-level rate; from the policy's rate to 1000)")
    parser.add_argument("--preference", type=arguments.preference, metavar="L1,L2", help="lambda to start with "
                        "(default: the middle of the simplex)")
    parser.add_argument("--command", type=command_vector, default=None, metavar="VX[,VY,WZ]",
                        help="walking: forward and lateral speed in m/s, yaw rate in rad/s, within the ranges the "
                        "policy was trained in (default 0.5,0,0 with --sim/--mujoco, 0 on a robot)")
    parser.add_argument("--command-sequence", metavar="FILE",
                        help="the command over time, from the policy's start: one row per line, 'seconds forward "
                        "lateral yaw_rate' (m/s, m/s, rad/s), each held until the next row's start, the last until "
                        "the run ends; # comments. Checked against the policy's ranges before anything starts; the "
                        "summary compares the end point with where the commands lead (examples/steering_sequence.txt)")
    parser.add_argument("--seconds", type=arguments.positive_float,
                        help="--sim/--mujoco: seconds of policy (default 10); robot: stop after this long")
    parser.add_argument("--hold-seconds", type=arguments.positive_float, default=1.0, metavar="S",
                        help="--sim/--mujoco: seconds in HOLD at least before the policy starts (default 1); it starts "
                        "once the robot stands still; with --hold-up shorter than the whole start, the robot stands "
                        "on its own for the rest")
    parser.add_argument("--skip-stand-still-check", action="store_true",
                        help="for experiments: start the policy when asked, even while the robot still sways in HOLD "
                        f"(by default the policy waits until the IMU reads below {GYRO_BOUND:g} rad/s for "
                        f"{WINDOW_S:g} s; a walker started while the robot sways can step into another gait)")
    parser.add_argument("--report", metavar="FILE.json", help="write the run's report as JSON (mode changes, "
                        "messages and rates, loop timing; with --sim/--mujoco: fell, distance, real-time figures)")
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
    if args.command is not None and args.command_sequence is not None:
        parser.error("give --command or --command-sequence, not both")
    if args.domain is not None and not 0 <= args.domain <= 232:
        parser.error(f"--domain must be a DDS domain id in [0, 232], got {args.domain}")
    simulated = args.sim or args.mujoco
    if args.scene and not simulated:
        parser.error("--scene is the simulated robot's model: use it with --sim or --mujoco")
    if args.scene and not os.path.isfile(args.scene):
        parser.error(f"no scene file at {args.scene}")
    if args.unitree_band is not None and not simulated:
        parser.error("--unitree-band is the simulated robot's gantry: use it with --sim or --mujoco")
    check_band_arguments(parser, args)
    seconds = args.seconds if args.seconds is not None or not simulated else 10.0
    try:
        setup = checked_setup(args, simulated, seconds)
        report = deploy(args, seconds, setup)
    except KeyboardInterrupt:  # before the loop took over Ctrl-C (which damps, then exits)
        raise SystemExit(f"{PROG}: interrupted before the deploy loop started; nothing was sent") from None
    except Exception as error:  # noqa: BLE001 - every failure is reported in one line unless -v
        if args.verbose:
            raise
        raise SystemExit(f"{PROG}: {one_line(error)}") from None
    if args.report:
        with open(args.report, "w") as f:
            json.dump(report, f, indent=1)
    print("\n".join(summary_lines(report, args.report)), flush=True)
    bridge = report.get("bridge")
    if bridge is not None and not bridge["kept_real_time"]:
        raise SystemExit(f"{PROG}: {behind_real_time(bridge)}")


def one_line(error: BaseException) -> str:
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


def checked_setup(args, simulated: bool, seconds: float | None = None) -> dict:
    """Everything the arguments must agree with the policy file on, checked from its metadata before the network,
    torch or DDS load: the preference, the command or command sequence, the LowCmd rate."""
    meta = read_metadata(args.policy)
    names = list(meta["objective_names"])
    preference = check_preference(args.preference if args.preference else [1.0 / len(names)] * len(names), names)
    check_lowcmd_rate(args.lowcmd_hz, 1.0 / float(meta["control_period_s"]))
    ranges, note = command_ranges_of(meta)
    if args.command is not None:
        command = args.command
    else:
        command = [0.5 if simulated and ranges is not None else 0.0, 0.0, 0.0]
    Command(ranges, command)  # refuses a component the policy was not trained with, or a value outside its range
    sequence = None
    if args.command_sequence is not None:
        sequence = read_command_sequence(args.command_sequence, ranges)
        last = sequence.rows[-1]
        if simulated and seconds is not None and last.start >= seconds:
            raise ValueError(f"{sequence.path}:{last.line}: the row at {last.start:g} s starts after the run's "
                             f"{seconds:g} s of policy; give --seconds (e.g. {last.start + 3:g})")
        command = list(sequence.rows[0].command)
    return {"preference": preference, "command": command, "command_note": note, "sequence": sequence}


def deploy(args, seconds: float | None, setup: dict) -> dict:
    # torch loads here, once checked_setup has held the arguments against the policy file's metadata
    from pchc_rsl.deploy.deployment import AutoSequence, Deployment, InProcessRobot, WallClockRobot
    from pchc_rsl.deploy.policy_step import PolicyStep

    policy = PolicyStep(args.policy)
    preference, command, sequence = setup["preference"], setup["command"], setup["sequence"]
    print(f"{PROG}: {policy.task} policy, {len(policy.joints.policy_joints)} of 29 joints driven, objectives "
          f"{', '.join(policy.objective_names)}, {1 / policy.control_period:.0f} Hz policy, LowCmd at "
          f"{args.lowcmd_hz:g} Hz", flush=True)
    if setup["command_note"]:
        print(f"{PROG}: {setup['command_note']}", flush=True)
    if sequence is not None:
        print(f"{PROG}: command sequence {sequence}, from the policy's start", flush=True)
    auto = AutoSequence(hold_s=args.hold_seconds) if (args.sim or args.mujoco) else None
    if args.mujoco:
        from pchc_rsl.deploy.simulator import G1Simulator  # MuJoCo: never loaded on a robot

        sim = G1Simulator(timestep=args.timestep, latency_s=args.latency_ms / 1e3, jitter_s=args.jitter_ms / 1e3,
                          hold_up_s=args.hold_up, pd_on_arrival=args.pd_on_arrival, scene=args.scene,
                          unitree_band=args.unitree_band, band_force_stays=args.band_force_stays)
        run = Deployment(policy, InProcessRobot(sim, policy.control_period, args.lowcmd_hz), preference, command, auto,
                         sequence=sequence, wait_still=not args.skip_stand_still_check)
        run.run(seconds)
        return with_fall(run.report(list(sim.trace)), sim.fell, sim.driven_distance()) | {
            "min_height_after_release": sim.min_height_after_release, "band_force_left": sim.band_force_left}

    bridge, bridge_report = None, None
    if args.sim:
        domain, interface = (random.randint(100, 232) if args.domain is None else args.domain), "lo"
        bridge_report = os.path.join(tempfile.mkdtemp(prefix="pchc-sim-bridge-"), "bridge.json")
        bridge = subprocess.Popen(
            [sys.executable, "-m", "pchc_rsl.cli.sim_bridge", "--domain", str(domain), "--network", interface,
             "--timestep", str(args.timestep), "--latency-ms", str(args.latency_ms), "--jitter-ms",
             str(args.jitter_ms), "--hold-up", str(args.hold_up), "--report", bridge_report,
             "--parent-pid", str(os.getpid())]
            + (["--viewer"] if args.sim_viewer else []) + (["--pd-on-arrival"] if args.pd_on_arrival else [])
            + (["--scene", args.scene] if args.scene else [])
            + (["--unitree-band", str(args.unitree_band)] if args.unitree_band is not None else [])
            + (["--band-force-stays"] if args.band_force_stays else []))
    else:
        domain, interface = (0 if args.domain is None else args.domain), args.network
    keys = console = None
    try:
        dds = DdsRobot(domain, interface, args.lowcmd_hz)
        keys = KeyReader()
        if keys.active:
            print(f"{PROG}: {KEY_HELP}", flush=True)
        inputs = [keys]
        if args.web is not None:
            console = DeployConsole(policy.objective_names, preference, policy.command_ranges, command, port=args.web)
            inputs.append(console)
            print(f"{PROG}: console at {console.url}", flush=True)
        run = Deployment(policy, WallClockRobot(dds, policy.control_period), preference, command, auto, inputs,
                         sequence=sequence, wait_still=not args.skip_stand_still_check)
        try:
            run.run(seconds, no_state_hint=no_state_hint(dds, interface, domain, args.sim),
                    no_state_timeout=30.0 if args.sim else 3.0)  # the bridge takes seconds to start on a busy machine
        finally:
            dds.close()  # the stream's last messages were the damping the run ended with
        report = run.report()
    finally:
        if keys is not None:
            keys.close()
        if console is not None:
            console.close()
        if bridge is not None:
            bridge.terminate()
            try:
                bridge.wait(timeout=20)
            except subprocess.TimeoutExpired:
                bridge.kill()
    if bridge_report is not None and os.path.exists(bridge_report):
        with open(bridge_report) as f:
            sim_report = json.load(f)
        trace = sim_report.pop("pose_trace")
        if "end_point" in report:
            report["end_point"] = run.end_point(trace)
        report = with_fall(report, sim_report["fell"], sim_report["base_distance"]) | {
            "bridge": judged(sim_report, report["lowstate"])}
    return report


def no_state_hint(dds, interface: str, domain: int, simulated: bool) -> str:
    where = f" on interface {interface}, DDS domain {domain}"
    if dds.rejected:
        return f"{where} ({dds.rejected} rejected: {dds.rejected_reason})"
    return where + ("" if simulated else "; is the robot on, in debug mode (L2+R2), and on that interface?")


def with_fall(report: dict, fell_in_sim: bool, distance: float) -> dict:
    """The simulated robot fell: its pelvis dropped before damping, or the watchdog damped it for a tilt or a
    collapse (it was falling; the pelvis may reach the ground only after the damping began)."""
    fell = bool(fell_in_sim) or report["reason"].startswith(("tilt", "collapse"))
    return report | {"fell": fell, "base_distance": round(float(distance), 4)}


LOWSTATE_HZ = 500.0
"""The rate at which a G1 publishes rt/lowstate, each a new reading."""


def lowstate_rate_note(report: dict) -> str:
    """LowState and new readings among them per second, with a warning when the new readings come far below the
    robot's 500: a simulator that runs slower than real time (the policy, paced by the wall clock, then acts on a
    robot in slow motion; a simulator whose LowState timer keeps publishing repeats its last state) or a lossy link.
    On a robot it is information: every reading is new."""
    states = report["lowstate"]
    if states["seconds"] < 1.0:
        return f", {states['fresh']} new readings"
    rate, fresh = states["received"] / states["seconds"], states["fresh"] / states["seconds"]
    note = f" ({rate:.0f} per second), {states['fresh']} new readings ({fresh:.0f} per second"
    if fresh < 0.9 * LOWSTATE_HZ and "bridge" not in report:  # pchc-sim-bridge's run is judged on it with its own
        note += (f", below the G1's {LOWSTATE_HZ:.0f}: a simulator that steps slower or runs behind real time (a "
                 "LowState timer of its own then repeats states), whose robot the policy then drives in slow motion, "
                 "or a lossy link")
    return note + ")"


def stand_still_line(report: dict) -> str:
    """How the policy's start waited for the robot to stand still ('' when it did not have to)."""
    still = report.get("stand_still", {})
    if "POLICY" not in [event[1] for event in report.get("events", [])]:
        return ""
    if still is None:
        return "  the policy started without waiting for the robot to stand still (--skip-stand-still-check)"
    if not still.get("waited_s"):
        return ""
    return (f"  the policy waited {still['waited_s']:.1f} s in HOLD for the robot to stand still (gyro below "
            f"{still['gyro_bound']:g} rad/s and tilt rate below {still['tilt_rate_bound']:g}/s for "
            f"{still['window_s']:g} s)")


def end_point_words(end: dict) -> str:
    """Where the pelvis ended against where the commands lead, both from the policy's start pose."""
    def pose(p):
        return f"({p[0]:+.2f} m, {p[1]:+.2f} m, {p[2]:+.0f} deg)"

    commanded = f"the commands lead to {pose(end['commanded'])}"
    if end["reached"] is None:
        return (f"{commanded} (forward, left, heading from the policy's start); the IMU turned "
                f"{end['imu_heading_deg']:+.0f} deg (a robot's position is not measured here)")
    return (f"{pose(end['reached'])} (forward, left, heading from the policy's start); {commanded}: "
            f"{end['off_m']:.2f} m apart, heading {end['heading_off_deg']:+.0f} deg off")


def summary_lines(report: dict, report_file: str | None) -> list[str]:
    """The end of a run for the operator's screen; the whole report is the --report JSON."""
    reason = f" ({report['reason']})" if report["reason"] else ""
    lines = [f"{PROG}: ended in {report['final_mode'].lower()}{reason} after {report['policy_seconds']:.1f} s of policy"]
    if still := stand_still_line(report):
        lines.append(still)
    stream = report.get("lowcmd")
    if stream is not None:
        priority = ("real-time priority" if stream["realtime_priority"] else
                    "normal priority: root or CAP_SYS_NICE gives its thread real-time priority")
        lines.append(f"  LowCmd: {report['messages_sent']} written at {stream['rate_hz']:g} Hz ({stream['loop_overruns']}"
                     f" late ticks, worst {stream['loop_worst_late_ms']:.1f} ms; {priority}); LowState: "
                     f"{report['messages_received']} received{lowstate_rate_note(report)}")
    else:
        lines.append(f"  LowCmd: {report['messages_sent']} applied; LowState: {report['messages_received']} read, "
                     f"{report['lowstate']['fresh']} new readings")
    if "loop" in report:
        loop = report["loop"]
        at = f" at {loop['worst_late_at_s']:.1f} s" if loop.get("worst_late_at_s") is not None else ""
        lines.append(f"  control loop: {loop['ticks']} ticks, {loop['overruns']} late (worst {loop['worst_late_ms']:.1f} ms"
                     f"{at})")
    if "fell" in report:
        lines.append(f"  simulated robot: {'FELL' if report['fell'] else 'did not fall'}, walked "
                     f"{report['base_distance']:.2f} m before damping")
    end = report.get("end_point")
    if end is not None:
        lines.append(f"  end point: {end_point_words(end)}")
    band = report.get("band_force_left") or (report.get("bridge") or {}).get("band_force_left")
    if band and any(band):
        lines.append(f"  unitree_mujoco's band: ({band[0]:.1f}, {band[1]:.1f}, {band[2]:.1f}) N left on the torso after "
                     "it let go")
    bridge = report.get("bridge")
    if bridge is not None:
        lines.append(f"  simulation: {bridge['sim_time']:.1f} s simulated in {bridge['wall_s']:.1f} s (real-time factor "
                     f"{bridge['real_time_factor']:.2f}), {bridge['late_share']:.0%} of physics steps late, slowest "
                     f"{bridge['slowest_step_ms']:.1f} ms; {bridge['commands_received']} LowCmd received, "
                     f"{bridge['commands_bad_crc']} with a bad CRC" + (
                         "" if bridge.get("fresh_states_per_second") is None else
                         f"; the deploy saw {bridge['fresh_states_per_second']:.0f} new LowState readings a second"))
    if report_file:
        lines.append(f"  report: {report_file}")
    return lines


if __name__ == "__main__":
    main()
