"""Steer a walker through a scripted sequence (forward, turn left, turn right, side step, stand) and compare where it
ends with where the commands integrate to, per preference, pushes off.

    python tools/diagnostics/steering_sequence.py policies/g1_walk.pt --num-envs 16
    python tools/diagnostics/steering_sequence.py policies/g1_walk.pt --sequence FILE --seconds 9 --phases
        # FILE in pchc-deploy's format

Why: tracking errors averaged over an episode can hide a walker that lags every change of command or drifts while
it stands; the end point of a whole sequence is what an operator steering it sees. The commanded pose is
integrated from the start pose with exact arcs, as ``pchc-deploy --command-sequence`` reports it
(``pchc_rsl.deploy.end_point``).
"""

from __future__ import annotations

import argparse
import math

import torch

from pchc_rsl.deploy.command_sequence import read_command_sequence
from pchc_rsl.deploy.end_point import in_start_frame, integrate_twist
from pchc_rsl.evaluation import evenly_spaced_preferences

SEQUENCE = [("forward", 3.0, (0.5, 0.0, 0.0)), ("turn left", 3.0, (0.3, 0.0, 0.5)),
            ("turn right", 3.0, (0.3, 0.0, -0.5)), ("side step left", 3.0, (0.0, 0.3, 0.0)),
            ("stand", 3.0, (0.0, 0.0, 0.0))]
"""(name, seconds, (v_x m/s, v_y m/s, w_z rad/s))."""


def integrate_commands(sequence, start_xy=(0.0, 0.0), start_yaw: float = 0.0) -> tuple[float, float, float]:
    """The pose (x, y, yaw) a robot reaches that follows the body-frame velocity commands of ``sequence`` exactly."""
    start = (float(start_xy[0]), float(start_xy[1]), float(start_yaw))
    return integrate_twist([(seconds, command) for _, seconds, command in sequence], start)


def phase_offset(start_xy, start_yaw: float, end_xy, phase) -> tuple[float, float]:
    """Where one phase ended against where its command takes the robot from the phase's own start pose: (ahead,
    left) in metres, in the frame of the heading the phase started with (negative ahead: it fell short)."""
    start = (float(start_xy[0]), float(start_xy[1]), float(start_yaw))
    _, seconds, command = phase
    commanded = in_start_frame(start, integrate_twist([(seconds, command)], start))
    reached = in_start_frame(start, (float(end_xy[0]), float(end_xy[1]), start_yaw))
    return reached[0] - commanded[0], reached[1] - commanded[1]


def sequence_from_file(path: str, ranges: dict, seconds: float | None = None) -> list:
    """A sequence in ``pchc-deploy --command-sequence``'s format (checked against ``ranges`` as the deploy checks it)
    as (name, seconds, command) phases, one per row; the last row held until ``seconds`` (default: 3 s)."""
    rows = read_command_sequence(path, ranges).rows
    end = rows[-1].start + 3.0 if seconds is None else seconds
    if end <= rows[-1].start:
        raise ValueError(f"{path}: the last row starts at {rows[-1].start:g} s, after the sequence ends ({end:g} s)")
    ends = [row.start for row in rows[1:]] + [end]
    return [(f"from {row.start:g} s", stop - row.start, row.command) for row, stop in zip(rows, ends)]


def run_sequence(env, policy, preference, sequence=SEQUENCE) -> dict:
    """One pass of ``sequence`` in every env at ``preference``: per env the end point's distance from the commanded
    one (m), the heading error (deg), whether it fell, and per phase its ``phase_offset`` (ahead, left)."""
    with torch.inference_mode():
        env.set_preference(preference)
        env.reset()
        obs = env.get_observations()
        start_xy = env.robot.base_pos[:, :2].clone()
        start_yaw = env.robot.yaw.clone()
        fell = torch.zeros(env.num_envs, dtype=torch.bool)
        phase_offsets = []
        for phase in sequence:
            _, seconds, command = phase
            phase_xy, phase_yaw = env.robot.base_pos[:, :2].clone(), env.robot.yaw.clone()
            for _ in range(int(round(seconds / env.dt))):
                env.commands[:] = torch.tensor(command)
                obs, _, dones, extras = env.step(policy(obs))
                fell |= dones.bool() & ~extras["time_outs"].bool()
            phase_offsets.append([phase_offset(phase_xy[i].tolist(), float(phase_yaw[i]), env.robot.base_pos[i, :2],
                                               phase) for i in range(env.num_envs)])
        end_xy, end_yaw = env.robot.base_pos[:, :2], env.robot.yaw
    errors, headings = [], []
    for i in range(env.num_envs):
        x, y, yaw = integrate_commands(sequence, start_xy[i].tolist(), float(start_yaw[i]))
        errors.append(math.hypot(float(end_xy[i, 0]) - x, float(end_xy[i, 1]) - y))
        headings.append(abs(math.degrees(math.remainder(float(end_yaw[i]) - yaw, 2 * math.pi))))
    kept = [i for i in range(env.num_envs) if not fell[i]]
    return {"falls": int(fell.sum()), "end_error": [errors[i] for i in kept], "heading_error": [headings[i] for i in kept],
            "phase_offsets": [[offsets[i] for i in kept] for offsets in phase_offsets]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoint")
    parser.add_argument("overrides", nargs="*", help="config overrides after the evaluation preset (KEY=VALUE)")
    parser.add_argument("--num-envs", type=int, default=16)
    parser.add_argument("--preferences", type=int, default=5, help="evenly spaced from (1, 0) to (0, 1)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--phases", action="store_true",
                        help="also each phase's end against its own command from the phase's start pose")
    parser.add_argument("--sequence", help="another sequence, a file in pchc-deploy --command-sequence's format "
                        "(examples/steering_sequence.txt is the built-in one); each row is a phase")
    parser.add_argument("--seconds", type=float, help="with --sequence: when it ends (default: 3 s after the last "
                        "row starts)")
    args = parser.parse_args()

    from pchc_rsl.evaluation.checkpoint import load_policy
    from pchc_rsl.runners import load_checkpoint
    from pchc_rsl.training.build import restore_config

    sequence = SEQUENCE
    if args.sequence:
        ranges = restore_config(load_checkpoint(args.checkpoint)["config"]).env.command_ranges
        sequence = sequence_from_file(args.sequence, ranges, args.seconds)
    seconds = sum(s for _, s, _ in sequence)
    overrides = ["env.push.enabled=false", *args.overrides]
    _, env, policy = load_policy(args.checkpoint, args.num_envs, args.seed, seconds + 1.0, None, overrides)
    print(f"{args.checkpoint}, {args.num_envs} runs per preference, pushes off: "
          + ", then ".join(f"{name} {s:g} s {c}" for name, s, c in sequence))
    print("| Preference | Falls | End point off, median (m) | max (m) | Heading off, median (deg) |")
    print("|---|---|---|---|---|")
    phases = []
    for preference in evenly_spaced_preferences(args.preferences):
        r = run_sequence(env, policy, preference, sequence)
        error, heading = torch.tensor(r["end_error"] or [math.nan]), torch.tensor(r["heading_error"] or [math.nan])
        shown = ", ".join(f"{x:.2f}" for x in preference)
        print(f"| ({shown}) | {r['falls']}/{args.num_envs} | {error.median():.2f} | {error.max():.2f} "
              f"| {heading.median():.1f} |", flush=True)
        phases.append((shown, r["phase_offsets"]))
    if args.phases:
        print("\nEach phase from its own start pose: median (ahead, left) offset of its end from its command's, m")
        print("| Preference | " + " | ".join(name for name, _, _ in sequence) + " |")
        print("|---" * (len(sequence) + 1) + "|")
        for shown, offsets in phases:
            medians = [torch.tensor(o or [(math.nan, math.nan)]).median(dim=0).values for o in offsets]
            print(f"| ({shown}) | " + " | ".join(f"{ahead:+.2f}, {left:+.2f}" for ahead, left in medians) + " |")


if __name__ == "__main__":
    main()
