"""pchc-play: watch a policy at chosen preferences, in a tiled video or in MuJoCo's viewer, and steer it live.

With --video: one episode per preference, rendered offscreen and tiled side by side, each tile labelled with its
lambda and live metrics. Without: MuJoCo's interactive viewer (passive mode) on one robot, with keys that move
lambda along the simplex, push the robot and reset it; this is the paper's dynamic preference switching, watched.
The environment is the one pchc-eval builds for the checkpoint (no randomisation, no noise, the paper's pushes).

Here the arguments are parsed; what they run (play_run.py) is imported after the OpenGL backend is chosen, because
MuJoCo reads MUJOCO_GL once, when it is first imported, and --video without a display needs EGL.
"""

from __future__ import annotations

import argparse

from pchc_rsl.utils.display import prefer_headless_gl


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pchc-play",
        description="Watch a checkpoint: with --video, a video with one tile per preference (MP4 or GIF); without, "
        "MuJoCo's interactive viewer with keys to change lambda, push and reset (needs a display).",
    )
    parser.add_argument("checkpoint", help="a model_<it>.pt written by pchc-train")
    parser.add_argument("overrides", nargs="*", metavar="KEY=VALUE",
                        help="config overrides after the evaluation preset, as on pchc-eval (e.g. "
                        "env.action_delay_s=0.02,0.02 to watch the policy with 20 ms of latency)")
    parser.add_argument("--preference", action="append", metavar="L1,L2",
                        help="a preference to show, repeatable (video default: 1,0 0.5,0.5 0,1; viewer: 0.5,0.5; "
                        "a checkpoint trained with --fixed-preference: that one)")
    parser.add_argument("--seconds", type=float,
                        help="length (video default: the task's episode length; viewer default: until closed)")
    parser.add_argument("--video", metavar="FILE", help="write FILE.mp4 or FILE.gif instead of opening the viewer")
    parser.add_argument("--width", type=int, default=480, help="tile width in pixels (video)")
    parser.add_argument("--height", type=int, default=360, help="tile height in pixels (video)")
    parser.add_argument("--fps", type=float, default=25.0, help="video frames per second of simulated time")
    parser.add_argument("--push-every", type=float, metavar="S",
                        help="push every S seconds (default: the evaluation preset's; 0: only on key press)")
    parser.add_argument("--viewer", choices=["native", "web"],
                        help="without --video: MuJoCo's window (native, needs a display) or a page in the browser "
                        "(web: viser; works over an SSH tunnel). Default: native with a display, web without")
    parser.add_argument("--host", default=None, help="web viewer: address to bind (default 127.0.0.1, this machine "
                        "only; reach it from elsewhere with ssh -L 8080:127.0.0.1:8080 HOST)")
    parser.add_argument("--port", type=int, default=None, help="web viewer: port (default 8080)")
    parser.add_argument("--speed", type=float, default=1.0, help="web viewer: simulation speed, x real time")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("-v", "--verbose", action="store_true", help="print error tracebacks")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_intermixed_args(argv)  # KEY=VALUE words may follow the options
    if args.video is not None:
        prefer_headless_gl()
    from pchc_rsl.cli.play_run import run  # loads MuJoCo: after the choice above

    run(args)


if __name__ == "__main__":
    main()
