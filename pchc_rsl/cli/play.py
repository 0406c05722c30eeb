"""pchc-play: watch a policy at chosen preferences, in a tiled video or in MuJoCo's viewer, and steer it live.

With --video: one episode per preference, rendered offscreen and tiled side by side, each tile labelled with its
lambda and live metrics. Without: MuJoCo's interactive viewer (passive mode) on one robot, with keys that move
lambda along the simplex, push the robot and reset it; this is the paper's dynamic preference switching, watched.
The environment is the one pchc-eval builds for the checkpoint (no randomisation, no noise, the paper's pushes).
"""

from __future__ import annotations

import argparse
import os

VIDEO_PREFERENCES = [(1.0, 0.0), (0.5, 0.5), (0.0, 1.0)]
VIEWER_PREFERENCE = (0.5, 0.5)


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
    from pchc_rsl.viewers.recording import has_display

    args = build_parser().parse_intermixed_args(argv)  # KEY=VALUE words may follow the options
    try:
        preferences = parse_preferences(args.preference, default_preferences(args.checkpoint, args.video))
        check_arguments(args)
    except ValueError as error:
        raise SystemExit(f"pchc-play: {error}") from None
    viewer = args.viewer or ("native" if has_display() else "web")
    if args.video is None and viewer == "native" and not has_display():
        raise SystemExit("pchc-play: no display for the native viewer (DISPLAY is not set). Use --viewer web (a "
                         "page in the browser), --video FILE.mp4 to render offscreen, or run under a display.")
    if args.video is not None and args.viewer is not None:
        raise SystemExit("pchc-play: --viewer shows the policy live; --video writes a file instead: pass one of them.")
    if args.video is not None and not has_display():
        os.environ.setdefault("MUJOCO_GL", "egl")  # headless offscreen rendering; read when mujoco is imported
    from pchc_rsl.envs.g1.render import RenderingUnavailable
    from pchc_rsl.viewers.web import WebViewerUnavailable

    try:
        if args.video:
            from pchc_rsl.viewers.recording import record_checkpoint_video

            path = record_checkpoint_video(args.checkpoint, preferences, args.video, args)
            print(f"pchc-play: wrote {path}")
        elif viewer == "web":
            watch_in_browser(args.checkpoint, preferences[0], args)
        else:
            watch_checkpoint(args.checkpoint, preferences[0], args)
    except (RenderingUnavailable, WebViewerUnavailable, ValueError, FileNotFoundError) as error:
        if args.verbose:
            raise
        raise SystemExit(f"pchc-play: {error}") from None


def default_preferences(checkpoint: str, video: str | None) -> list[tuple[float, ...]]:
    """What to show without --preference: the one preference a checkpoint trained with --fixed-preference saw, else
    the video's three or the viewer's one. A file that cannot be read gets the usual defaults here and its error
    where the policy is loaded."""
    from pchc_rsl.evaluation import trained_preference
    from pchc_rsl.runners import load_checkpoint

    try:
        fixed = trained_preference(load_checkpoint(checkpoint).get("config") or {})
    except (FileNotFoundError, ValueError):
        fixed = None
    if fixed is not None:
        return [fixed]
    return VIDEO_PREFERENCES if video else [VIEWER_PREFERENCE]


def parse_preferences(texts: list[str] | None, default: list[tuple[float, ...]]) -> list[tuple[float, ...]]:
    """'L1,L2' strings -> validated preference tuples (the length is checked against the task later)."""
    from pchc_rsl.preference import validate_preference

    if not texts:
        return default
    preferences = []
    for text in texts:
        try:
            values = [float(x) for x in text.split(",")]
        except ValueError:
            raise ValueError(f"--preference {text}: expected numbers separated by commas, e.g. 0.3,0.7.") from None
        validate_preference(values, len(values))
        preferences.append(tuple(values))
    return preferences


def check_arguments(args) -> None:
    from pchc_rsl.viewers.video import check_frame_size, check_video_path

    if args.video is not None:
        check_video_path(args.video)
        check_frame_size(args.width, args.height)
    if args.seconds is not None and not args.seconds > 0:
        raise ValueError(f"--seconds {args.seconds}: must be > 0, e.g. --seconds 5.")
    if args.push_every is not None and not args.push_every >= 0:
        raise ValueError(f"--push-every {args.push_every}: must be >= 0 seconds (0: push only on key press).")
    if not args.fps > 0:
        raise ValueError(f"--fps {args.fps}: must be > 0, e.g. --fps 25.")
    if args.port is not None and not 0 < args.port < 65536:
        raise ValueError(f"--port {args.port}: must be a TCP port in [1, 65535], e.g. --port 8080.")
    if not 0 < args.speed <= 10:
        raise ValueError(f"--speed {args.speed}: must be in (0, 10], e.g. --speed 0.5 for half speed.")


def watch_in_browser(checkpoint: str, preference, args) -> None:
    """The policy in a page served by viser on --host:--port, until Ctrl-C (or --seconds of simulation)."""
    from pchc_rsl.evaluation import TASK_EVALUATION, check_objectives, load_policy
    from pchc_rsl.viewers.web import DEFAULT_HOST, DEFAULT_PORT, WebViewer, check_port, require_viser

    host, port = args.host or DEFAULT_HOST, args.port or DEFAULT_PORT
    require_viser()
    check_port(host, port)  # before the checkpoint loads: a taken port is known at once
    print(f"pchc-play: loading {checkpoint}...", flush=True)
    task, env, policy = load_policy(checkpoint, 1, args.seed, 1e6, args.push_every, args.overrides)
    check_objectives(env, [preference], checkpoint)
    evaluation = TASK_EVALUATION.get(task)
    viewer = WebViewer(env, policy, preference, host, port, args.speed,
                       pushes=evaluation.pushes if evaluation is not None else {})
    print(f"pchc-play: open {viewer.url} in a browser (on another machine: ssh -L {port}:{host}:{port} THIS_HOST, "
          f"then http://localhost:{port}); Ctrl-C stops", flush=True)
    try:
        viewer.run(args.seconds)
    finally:
        viewer.close()
    print(f"pchc-play: stopped after {viewer.steps * viewer.dt:.1f} s at lambda {tuple(env.preference[0].tolist())}")


def watch_checkpoint(checkpoint: str, preference, args) -> None:
    """The policy in MuJoCo's window until it is closed (or --seconds of simulation)."""
    from pchc_rsl.evaluation import check_objectives, load_policy
    from pchc_rsl.viewers.native import run_viewer

    task, env, policy = load_policy(checkpoint, 1, args.seed, 1e6, args.push_every, args.overrides)  # no time-outs while watching
    if task == "toy":
        raise SystemExit("pchc-play: the toy task has no MuJoCo scene to view; pass --video toy.gif for an animated "
                         "plot of its trajectories.")
    check_objectives(env, [preference], checkpoint)
    steps = run_viewer(env, policy, preference, args.seconds)
    print(f"pchc-play: viewer closed after {steps * env.dt:.1f} s at lambda {tuple(env.preference[0].tolist())}")


if __name__ == "__main__":
    main()
