"""Videos of a checkpoint: one episode per preference, rendered offscreen (the G1) or plotted (the toy), tiled side
by side with each tile labelled with its lambda and live metrics. Used by pchc-play --video and pchc-eval --video."""

from __future__ import annotations

import argparse
import os

import torch

from pchc_rsl.envs.g1.render import G1Renderer
from pchc_rsl.envs.toy_render import ToyPlot
from pchc_rsl.evaluation.checkpoint import TOY_STEPS_PER_SECOND, check_objectives, load_policy
from pchc_rsl.viewers.overlay import tile_label
from pchc_rsl.viewers.video import VideoWriter, label, tile


def record_checkpoint_video(checkpoint: str, preferences, path: str, args, prog: str = "pchc-play") -> str:
    """One episode per preference of ``args.seconds`` (default: the task's episode length), tiled into ``path``.

    ``args`` carries seed, seconds, push_every, overrides, width, height and fps (pchc-play's options); progress
    lines start with ``prog``."""
    print(f"{prog}: loading {checkpoint} and building {len(preferences)} env(s)...", flush=True)
    task, env, policy = load_policy(checkpoint, len(preferences), args.seed, args.seconds, args.push_every,
                                    args.overrides)
    check_objectives(env, preferences, checkpoint)
    if task == "toy":
        renderer, dt = ToyPlot(env, args.width, args.height), 1.0 / TOY_STEPS_PER_SECOND
    else:
        renderer, dt = G1Renderer(env, args.width, args.height), env.dt
    seconds = args.seconds if args.seconds is not None else env.max_episode_length * dt
    print(f"{prog}: simulating and rendering {seconds:g} s at {len(preferences)} preference(s)...", flush=True)
    try:
        frames = record_video(env, policy, renderer, preferences, path, seconds, dt, args.fps)
    finally:
        renderer.close()
    return f"{path} ({frames} frames, {len(preferences)} preferences, {seconds:g} s)"


def record_video(env, policy, renderer, preferences, path: str, seconds: float, dt: float, fps: float) -> int:
    """Step env i at preferences[i] for ``seconds``, a frame every round(1 / (fps dt)) steps; returns the frame count.

    The frame rate written is the one achieved, 1 / (frame interval), so the video plays in real time."""
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

    RenderingUnavailable (from pchc_rsl.envs.g1.render) without an OpenGL context (pchc-eval chooses EGL without a
    display: pchc_rsl.utils.display)."""
    video_args = argparse.Namespace(seed=args.seed, seconds=args.episode_length, push_every=None, width=320,
                                    overrides=getattr(args, "overrides", []),
                                    height=240, fps=25.0)
    written = []
    for checkpoint in checkpoints:
        run = os.path.basename(os.path.dirname(os.path.abspath(checkpoint)))
        path = os.path.join(args.output, f"{run}_{os.path.splitext(os.path.basename(checkpoint))[0]}.mp4")
        written.append(record_checkpoint_video(checkpoint, preferences, path, video_args, prog="pchc-eval"))
        print(f"pchc-eval: wrote {written[-1]}")
    return written
