"""Policy steps per second of the G1 walking env against the bare batched physics it is built on.

For each N and thread count, in the same run: (a) G1Env.step with a held standing action (observations,
rewards, contacts, pushes, resets: everything a training step does) and (b) BatchedMuJoCo.step alone on the same
compiled model from the same standing states with the same control: the physics limit. Robots start standing on
the ground (both feet in contact) and the window is short enough that they stay up. Prints medians of repeats and
the ratio env / bare (target >= 0.9 from 256 envs up).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import torch

from pchc_rsl.cli.common import make_env
from pchc_rsl.configs import task_config
from pchc_rsl.envs.physics import BatchedMuJoCo


def measure(num_envs: int, threads: int, steps: int, repeats: int, task: str) -> tuple[float, float]:
    cfg = task_config(task)
    cfg.num_envs = num_envs
    cfg.env.num_threads = threads
    cfg.env.randomization.enabled = False  # one model, as the bare loop uses
    env = make_env(cfg)
    bare = BatchedMuJoCo(env.model, num_envs, cfg.env.decimation, threads)
    action = torch.zeros(num_envs, env.num_actions)
    ctrl = env.default_joint_pos.double().expand(num_envs, -1).numpy().copy()
    env_times, bare_times = [], []
    for _ in range(repeats):
        env.reset()
        start_state = env.physics.state.copy()
        start = time.perf_counter()
        for _ in range(steps):
            env.step(action)
        env_times.append(time.perf_counter() - start)
        bare.state[:] = start_state
        start = time.perf_counter()
        for _ in range(steps):
            bare.step(ctrl)
        bare_times.append(time.perf_counter() - start)
    return num_envs * steps / statistics.median(env_times), num_envs * steps / statistics.median(bare_times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--num-envs", type=int, nargs="+", default=[64, 256, 1024])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--steps", type=int, default=20, help="policy steps per timing (0.4 s of standing)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--task", default="g1-walk", help="g1-walk (paper physics) or g1-walk-fast")
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(f"task {args.task}; policy steps/s (env steps, all envs), median of {args.repeats}")
    print(f"{'N':>6}{'threads':>9}{'env':>12}{'bare physics':>14}{'env/bare':>10}")
    for n in args.num_envs:
        for threads in args.threads:
            env_rate, bare_rate = measure(n, threads, args.steps, args.repeats, args.task)
            print(f"{n:>6}{threads:>9}{env_rate:>12.0f}{bare_rate:>14.0f}{env_rate / bare_rate:>10.2f}", flush=True)


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
