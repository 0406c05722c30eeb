"""pchc-eval: the paper's evaluation of one or more checkpoints at fixed preferences.

Here the arguments are parsed; what they run (eval_run.py) is imported after the OpenGL backend is chosen, because
MuJoCo reads MUJOCO_GL once, when it is first imported, and --video without a display needs EGL."""

from __future__ import annotations

import argparse
import re

from pchc_rsl.cli import arguments
from pchc_rsl.utils.display import prefer_headless_gl

PROG = "pchc-eval"


def build_parser() -> argparse.ArgumentParser:
    parser = arguments.Parser(
        prog=PROG,
        description="Evaluate checkpoints at fixed preferences under the task's evaluation preset (G1: no "
        "randomisation, no noise, the paper's pushes; toy: undiscounted returns of each goal); write results.json, "
        "table.md, pareto.png (and energy_curve.png for fall recovery, switching.png with --switch). A checkpoint "
        "trained with --fixed-preference is evaluated at that preference only: one point beside the fronts.",
    )
    parser.add_argument("checkpoints", nargs="+", metavar="CKPT [KEY=VALUE ...]",
                        help="checkpoints, then any config overrides applied after the evaluation preset, as on "
                        "pchc-train (e.g. env.action_delay_s=0.02,0.02 env.push.velocity=1.5,1.5)")
    parser.add_argument("--preferences", type=arguments.at_least_two, default=5,
                        help="evenly spaced preferences from (1,0) to (0,1) (default 5)")
    parser.add_argument("--preference", action="append", type=arguments.preference, metavar="L1,L2",
                        help="explicit preference(s) instead; repeatable")
    parser.add_argument("--num-envs", type=arguments.positive_int, default=64,
                        help="parallel envs (default 64: with --episodes 2, 128 episodes per preference, a few "
                             "minutes on 2 CPU cores; the paper uses 1000 envs)")
    parser.add_argument("--episodes", type=arguments.positive_int, default=2,
                        help="episodes per env and preference (default 2)")
    parser.add_argument("--seed", type=arguments.seed, default=0,
                        help="seed of the evaluation envs (initial states, push times and directions; default 0)")
    parser.add_argument("--device", default="cpu", help="torch device of the policy and Warp physics (default cpu)")
    parser.add_argument("--robustness", action="store_true",
                        help="instead of the tables: every preference under the deployment shifts (latency, "
                        "physics, friction, mass, actuator strength, noise, commands, push sweep); writes "
                        "robustness.json, robustness.md, robustness.png")
    parser.add_argument("--condition", action="append", metavar="NAME",
                        help="with --robustness: only these conditions (repeatable; names as in robustness.md)")
    parser.add_argument("--push-presets", nargs="+", metavar="NAME",
                        help="push presets in place of the task's (mild, strong), e.g. mild-v1 strong-v1 (the "
                        "presets before the calibration); the table keeps its mild and strong columns")
    parser.add_argument("--force", action="store_true", help="write into an --output folder that holds results")
    parser.add_argument("--episode-length", type=arguments.positive_float, help="override the episode length (s)")
    parser.add_argument("--switch", action="store_true", help="also switch lambda (0,1) -> (1,0) mid-episode (G1)")
    parser.add_argument("--output", default="eval", help="folder for the results (default: eval)")
    parser.add_argument("--video", action="store_true", help="also write a video per checkpoint (see pchc-play)")
    parser.add_argument("-v", "--verbose", action="store_true", help="print the models and error tracebacks")
    return parser


OVERRIDE_SHAPE = re.compile(r"^[A-Za-z_][\w.]*=")


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_intermixed_args(argv)  # KEY=VALUE words may follow the options
    args.overrides = [word for word in args.checkpoints if OVERRIDE_SHAPE.match(word)]
    args.checkpoints = [word for word in args.checkpoints if not OVERRIDE_SHAPE.match(word)]
    if not args.checkpoints:
        raise SystemExit(f"{PROG}: give a checkpoint before the KEY=VALUE overrides.")
    if args.video:
        prefer_headless_gl()
    from pchc_rsl.cli.eval_run import run  # loads MuJoCo: after the choice above

    run(args)


if __name__ == "__main__":
    main()
