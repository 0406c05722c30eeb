"""What pchc-play runs once its arguments are parsed (cli/play.py) and MuJoCo's OpenGL backend is chosen: the
preferences checked, then the video, the browser viewer or MuJoCo's window."""

from __future__ import annotations

from pchc_rsl.envs.g1.render import RenderingUnavailable
from pchc_rsl.evaluation import TASK_EVALUATION, check_objectives, load_policy, trained_preference
from pchc_rsl.preference import validate_preference
from pchc_rsl.runners import load_checkpoint
from pchc_rsl.utils.display import has_display
from pchc_rsl.viewers.native import run_viewer
from pchc_rsl.viewers.recording import record_checkpoint_video
from pchc_rsl.viewers.video import check_frame_size, check_video_path
from pchc_rsl.viewers.web import WebViewer
from pchc_rsl.viewers.web_page import DEFAULT_HOST, DEFAULT_PORT, WebViewerUnavailable, check_port, require_viser

VIDEO_PREFERENCES = [(1.0, 0.0), (0.5, 0.5), (0.0, 1.0)]
VIEWER_PREFERENCE = (0.5, 0.5)


def run(args) -> None:
    """Show ``args.checkpoint`` as pchc-play's parsed arguments say."""
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
    try:
        if args.video:
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
    try:
        fixed = trained_preference(load_checkpoint(checkpoint).get("config") or {})
    except (FileNotFoundError, ValueError):
        fixed = None
    if fixed is not None:
        return [fixed]
    return VIDEO_PREFERENCES if video else [VIEWER_PREFERENCE]


def parse_preferences(texts: list[str] | None, default: list[tuple[float, ...]]) -> list[tuple[float, ...]]:
    """'L1,L2' strings -> validated preference tuples (the length is checked against the task later)."""
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
    task, env, policy = load_policy(checkpoint, 1, args.seed, 1e6, args.push_every, args.overrides)  # no time-outs while watching
    if task == "toy":
        raise SystemExit("pchc-play: the toy task has no MuJoCo scene to view; pass --video toy.gif for an animated "
                         "plot of its trajectories.")
    check_objectives(env, [preference], checkpoint)
    steps = run_viewer(env, policy, preference, args.seconds)
    print(f"pchc-play: viewer closed after {steps * env.dt:.1f} s at lambda {tuple(env.preference[0].tolist())}")
