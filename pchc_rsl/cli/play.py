"""pchc-play: watch a policy at chosen preferences, in a tiled video or in MuJoCo's viewer, and steer it live.

With --video: one episode per preference, rendered offscreen and tiled side by side, each tile labelled with its
lambda and live metrics. Without: MuJoCo's interactive viewer (passive mode) on one robot, with keys that move
lambda along the simplex, push the robot and reset it; this is the paper's dynamic preference switching, watched.
The environment is the one pchc-eval builds for the checkpoint (no randomisation, no noise, the paper's pushes).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections import deque

TOY_STEPS_PER_SECOND = 10
"""The toy has no physical time: its video shows this many steps per second."""
LAMBDA_STEP = 0.1
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


def has_display() -> bool:
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def main(argv: list[str] | None = None) -> None:
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
    from pchc_rsl.envs.g1_render import RenderingUnavailable
    from pchc_rsl.web_viewer import WebViewerUnavailable

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
    from pchc_rsl.video import check_frame_size, check_video_path

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


# ---------------------------------------------------------------------------- the env and policy of a checkpoint
def load_policy(path: str, num_envs: int, seed: int, episode_length_s: float | None, push_every: float | None,
                overrides: list[str] = ()):
    """The checkpoint's env under pchc-eval's evaluation preset (its first push preset) and ``overrides``, and its
    inference policy.

    Returns (task, env, policy); refuses tasks without a scene to show in one line."""
    from pchc_rsl.cli.common import restore_config
    from pchc_rsl.cli.overrides import apply_overrides
    from pchc_rsl.evaluation import TASK_EVALUATION, evaluation_preset, loaded_policy
    from pchc_rsl.runners import load_checkpoint

    try:
        config = load_checkpoint(path).get("config") or {}
    except (FileNotFoundError, ValueError) as error:
        raise SystemExit(f"pchc-play: {error}") from None
    task = config.get("task")
    if task != "toy" and task not in TASK_EVALUATION:
        shown = ", ".join(sorted(TASK_EVALUATION) + ["toy"])
        raise SystemExit(f"pchc-play: {path} is for task '{task}'; pchc-play shows {shown}.")
    cfg = restore_config(config)
    if task == "toy":
        if episode_length_s is not None:
            cfg.env.episode_length = max(1, round(episode_length_s * TOY_STEPS_PER_SECOND))
    else:
        evaluation = TASK_EVALUATION[task]
        cfg = evaluation_preset(cfg, evaluation.push_presets[0], evaluation)
        if episode_length_s is not None:
            cfg.env.episode_length_s = episode_length_s
        if push_every is not None:
            interval = push_every if push_every > 0 else 1e9  # 0: never by itself, still on a key press
            cfg.env.push.interval_s = (interval, interval)
    try:
        apply_overrides(cfg, list(overrides))
    except ValueError as error:
        raise SystemExit(f"pchc-play: {error}") from None
    cfg.num_envs, cfg.seed, cfg.device = num_envs, seed, "cpu"
    runner, policy = loaded_policy(path, cfg)
    return task, runner.env, policy


def check_objectives(env, preferences, path: str) -> None:
    m = env.num_objectives
    for lam in preferences:
        if len(lam) != m:
            names = ", ".join(env.cfg.objective_names)
            raise SystemExit(f"pchc-play: preference {lam} has {len(lam)} entries; {path} has {m} objectives "
                             f"({names}): pass --preference with {m} numbers summing to 1.")


# ---------------------------------------------------------------------------- labels
def _number(value: float, fmt: str) -> str:
    return "-" if value != value else format(value, fmt)


def live_metrics(env, i: int, falls: int) -> list[tuple[str, str]]:
    """(name, value) pairs shown next to a robot: stride or energy, the last push's deviation, falls or standing."""
    import torch

    if not hasattr(env, "episode_metrics"):  # the toy: how far from each goal
        distance = (env.pos[i] - env.goals).norm(dim=-1)
        return [(f"distance to {n}", f"{d:.2f}") for n, d in zip("AB", distance.tolist())]
    metrics = {k: float(v[0]) for k, v in env.episode_metrics(torch.tensor([i])).items()}
    if "energy_overall" in metrics:
        rows = [("energy", _number(metrics["energy_overall"], ".0f") + " J/s")]
    else:
        rows = [("stride", _number(metrics.get("stride_length", math.nan), ".2f") + " m")]
    pushed = bool(env.pushes.active[i]) or not math.isnan(metrics.get("push_deviation", math.nan))
    deviation = float(env.pushes.max_deviation[i]) if pushed else math.nan
    rows.append(("push deviation", _number(deviation, ".2f") + " m"))
    if hasattr(env, "reached_standing"):
        rows.append(("state", "standing" if bool(env.reached_standing[i]) else "getting up"))
    else:
        rows.append(("falls", str(falls)))
    return rows


def preference_row(env, i: int) -> tuple[str, str]:
    """("lambda (obj_1, obj_2)", "(0.30, 0.70)")."""
    lam = ", ".join(f"{x:.2f}" for x in env.preference[i].tolist())
    return f"lambda ({', '.join(env.cfg.objective_names)})", f"({lam})"


def tile_label(env, i: int, falls: int) -> list[str]:
    name, value = preference_row(env, i)
    return [f"{name} = {value}"] + [f"{name}: {value}" for name, value in live_metrics(env, i, falls)]


# ---------------------------------------------------------------------------- video
def record_checkpoint_video(checkpoint: str, preferences, path: str, args) -> str:
    """One episode per preference of ``args.seconds`` (default: the task's episode length), tiled into ``path``."""
    print(f"pchc-play: loading {checkpoint} and building {len(preferences)} env(s)...", flush=True)
    task, env, policy = load_policy(checkpoint, len(preferences), args.seed, args.seconds, args.push_every,
                                    args.overrides)
    check_objectives(env, preferences, checkpoint)
    if task == "toy":
        from pchc_rsl.envs.toy_render import ToyPlot

        renderer, dt = ToyPlot(env, args.width, args.height), 1.0 / TOY_STEPS_PER_SECOND
    else:
        from pchc_rsl.envs.g1_render import G1Renderer

        renderer, dt = G1Renderer(env, args.width, args.height), env.dt
    seconds = args.seconds if args.seconds is not None else env.max_episode_length * dt
    print(f"pchc-play: simulating and rendering {seconds:g} s at {len(preferences)} preference(s)...", flush=True)
    try:
        frames = record_video(env, policy, renderer, preferences, path, seconds, dt, args.fps)
    finally:
        renderer.close()
    return f"{path} ({frames} frames, {len(preferences)} preferences, {seconds:g} s)"


def record_video(env, policy, renderer, preferences, path: str, seconds: float, dt: float, fps: float) -> int:
    """Step env i at preferences[i] for ``seconds``, a frame every round(1 / (fps dt)) steps; returns the frame count.

    The frame rate written is the one achieved, 1 / (frame interval), so the video plays in real time."""
    import torch

    from pchc_rsl.video import VideoWriter, label, tile

    steps = max(1, round(seconds / dt))
    every = max(1, round(1.0 / (fps * dt)))
    falls = [0] * env.num_envs
    with torch.inference_mode(), VideoWriter(path, 1.0 / (every * dt)) as video:
        env.set_preference(torch.tensor(preferences, dtype=torch.float32))
        env.reset()
        if hasattr(renderer, "record"):
            renderer.record()
        obs = env.get_observations()
        for step in range(steps):
            if step % every == 0:
                video.append(tile([label(renderer.render(env, i), tile_label(env, i, falls[i]))
                                   for i in range(env.num_envs)]))
            obs, _, _, extras = env.step(policy(obs))
            if hasattr(renderer, "record"):
                renderer.record()
            finished = extras.get("episode_metrics")
            if finished is not None:
                for env_id in finished["env_ids"][finished["fell"]].tolist():
                    falls[env_id] += 1
        return video.count


def write_eval_videos(checkpoints: list[str], preferences, args) -> list[str]:
    """pchc-eval --video: the tiled video of each checkpoint at the evaluated preferences, next to the tables.

    Called before the evaluation, so that a headless run can still choose MUJOCO_GL=egl before mujoco loads."""
    if not has_display():
        os.environ.setdefault("MUJOCO_GL", "egl")
    from pchc_rsl.envs.g1_render import RenderingUnavailable

    video_args = argparse.Namespace(seed=args.seed, seconds=args.episode_length, push_every=None, width=320,
                                    overrides=getattr(args, "overrides", []),
                                    height=240, fps=25.0)
    written = []
    for checkpoint in checkpoints:
        run = os.path.basename(os.path.dirname(os.path.abspath(checkpoint)))
        path = os.path.join(args.output, f"{run}_{os.path.splitext(os.path.basename(checkpoint))[0]}.mp4")
        try:
            written.append(record_checkpoint_video(checkpoint, preferences, path, video_args))
        except RenderingUnavailable as error:
            raise SystemExit(f"pchc-eval --video: {error}") from None
        print(f"pchc-eval: wrote {written[-1]}")
    return written


# ---------------------------------------------------------------------------- interactive viewer
RIGHT, LEFT, SPACE, BACKSPACE = 262, 263, 32, 259
"""GLFW key codes of the keys the passive viewer leaves to its user (its letters toggle rendering flags)."""
KEYS = {RIGHT: "right", LEFT: "left", SPACE: "push", BACKSPACE: "reset"}


def key_help(objective_names: list[str]) -> str:
    first, second = objective_names
    return f"Left: more {first}\nRight: more {second}\nSpace: push\nBackspace: reset"


class LiveControls:
    """The viewer's keys: queued from the viewer's thread, applied between policy steps on env 0."""

    def __init__(self, env) -> None:
        self.env, self.pending = env, deque()

    def on_key(self, keycode: int) -> None:
        if keycode in KEYS:
            self.pending.append(KEYS[keycode])

    def apply(self) -> bool:
        """Apply the queued keys; True if any did (the policy then needs fresh observations)."""
        import torch

        env, changed = self.env, bool(self.pending)
        while self.pending:
            action = self.pending.popleft()
            if action in ("left", "right") and env.num_objectives == 2:
                t = float(env.preference[0, 1]) + (LAMBDA_STEP if action == "right" else -LAMBDA_STEP)
                t = min(1.0, max(0.0, round(t / LAMBDA_STEP) * LAMBDA_STEP))
                env.set_preference(torch.tensor([1.0 - t, t]))
            elif action == "push":
                env.pushes.countdown[:] = 1  # the next step pushes, at the preset's strength, in a random direction
            elif action == "reset":
                env.reset()
        return changed


def watch_in_browser(checkpoint: str, preference, args) -> None:
    """The policy in a page served by viser on --host:--port, until Ctrl-C (or --seconds of simulation)."""
    from pchc_rsl.evaluation import TASK_EVALUATION
    from pchc_rsl.web_viewer import DEFAULT_HOST, DEFAULT_PORT, WebViewer, check_port, require_viser

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
    task, env, policy = load_policy(checkpoint, 1, args.seed, 1e6, args.push_every, args.overrides)  # no time-outs while watching
    if task == "toy":
        raise SystemExit("pchc-play: the toy task has no MuJoCo scene to view; pass --video toy.gif for an animated "
                         "plot of its trajectories.")
    check_objectives(env, [preference], checkpoint)
    steps = run_viewer(env, policy, preference, args.seconds)
    print(f"pchc-play: viewer closed after {steps * env.dt:.1f} s at lambda {tuple(env.preference[0].tolist())}")


def run_viewer(env, policy, preference, seconds: float | None) -> int:
    """MuJoCo's passive viewer on env 0 in real time until closed (or ``seconds`` of simulation); returns steps."""
    import mujoco
    import torch

    from pchc_rsl.envs.g1_render import add_push_arrow, visual_model
    from pchc_rsl.passive_viewer import passive_viewer

    model = visual_model(env)
    data = mujoco.MjData(model)
    controls = LiveControls(env)
    steps, falls = 0, 0
    with passive_viewer(model, data, key_callback=controls.on_key, show_left_ui=False,
                        show_right_ui=False) as handle:
        with handle.lock():
            handle.cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
            handle.cam.trackbodyid = model.body("pelvis").id
            handle.cam.distance, handle.cam.azimuth, handle.cam.elevation = 3.0, 150.0, -15.0
        with torch.inference_mode():
            env.set_preference(torch.tensor(preference, dtype=torch.float32))
            env.reset()
            obs = env.get_observations()
            while handle.is_running() and (seconds is None or steps * env.dt < seconds):
                start = time.perf_counter()
                if controls.apply():
                    obs = env.get_observations()
                obs, _, _, extras = env.step(policy(obs))
                falls += int(extras["episode_metrics"]["fell"].sum())
                steps += 1
                with handle.lock():
                    data.qpos[:] = env.physics.qpos[0].cpu().numpy()
                    mujoco.mj_forward(model, data)
                    handle.user_scn.ngeom = 0
                    if bool(env.pushes.active[0]):
                        add_push_arrow(handle.user_scn, env.physics.qpos[0, :3].cpu().numpy(),
                                       env.pushes.direction[0].cpu().numpy())
                rows = [preference_row(env, 0)] + live_metrics(env, 0, falls)
                handle.set_texts([
                    (None, mujoco.mjtGridPos.mjGRID_TOPLEFT, "\n".join(n for n, _ in rows),
                     "\n".join(v for _, v in rows)),
                    (None, mujoco.mjtGridPos.mjGRID_BOTTOMLEFT, key_help(env.cfg.objective_names), ""),
                ])
                handle.sync()
                time.sleep(max(0.0, env.dt - (time.perf_counter() - start)))
    return steps


if __name__ == "__main__":
    main()
