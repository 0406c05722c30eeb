"""Whole training loop against bare physics: where an iteration's time goes, and how close it gets to the limit.

    python tools/bench_train.py [--num-envs 256 1024 4096] [--iterations 2] [--threads 1]

For each N, in the same process: a PCHC runner on the task (randomised envs, as in training) runs warm-up and
timed iterations of rsl-rl's loop (rollout of num_steps_per_env steps: act, env.step, process_env_step; then
compute_returns and the PPO update), collection and learning timed apart; then BatchedMuJoCo.step alone on the same
model variants and thread count, from standing states, for as many policy steps: the physics limit. Prints env
steps per second of collection, of the whole loop, of bare physics, and the ratio whole loop / bare physics.
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from pchc_rsl.cli.common import make_runner
from pchc_rsl.configs import task_config
from pchc_rsl.envs.physics import BatchedMuJoCo


def timed_iteration(runner) -> tuple[float, float]:
    """One iteration of OnPolicyRunner.learn's body; (collection s, learning s)."""
    alg, env = runner.alg, runner.env
    obs = env.get_observations().to(runner.device)
    start = time.perf_counter()
    with torch.inference_mode():
        for _ in range(runner.cfg["num_steps_per_env"]):
            actions = alg.act(obs)
            obs, rewards, dones, extras = env.step(actions.to(env.device))
            obs, rewards, dones = obs.to(runner.device), rewards.to(runner.device), dones.to(runner.device)
            alg.process_env_step(obs, rewards, dones, extras)
        collected = time.perf_counter()
        alg.compute_returns(obs)
    alg.update()
    return collected - start, time.perf_counter() - collected


def bare_physics_rate(env, steps: int, threads: int) -> float:
    physics = env.physics
    bare = BatchedMuJoCo(physics.models, env.num_envs, physics.substeps, threads,
                         with_body_forces=physics.body_forces is not None)
    with torch.inference_mode():  # the env's buffers are inference tensors once stepped in that mode
        env.reset()
    bare.state[:] = env.physics.state
    ctrl = env.default_joint_pos.double().expand(env.num_envs, -1).numpy().copy()
    start = time.perf_counter()
    for _ in range(steps):
        bare.step(ctrl)
    return env.num_envs * steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="g1-walk-fast")
    parser.add_argument("--num-envs", type=int, nargs="+", default=[256, 1024, 4096])
    parser.add_argument("--iterations", type=int, default=2, help="timed iterations (after one warm-up)")
    parser.add_argument("--threads", type=int, default=1, help="physics threads and torch threads")
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(f"{args.task}, {args.threads} thread(s), device {args.device}; env steps/s; median of {args.iterations}")
    print(f"{'N':>6}{'collect s':>11}{'learn s':>9}{'collect/s':>11}{'loop/s':>9}{'bare/s':>9}{'loop/bare':>11}")
    for n in args.num_envs:
        cfg = task_config(args.task)
        cfg.num_envs, cfg.device = n, args.device
        cfg.env.num_threads = args.threads
        runner = make_runner(cfg)
        runner.alg.train_mode()
        timed_iteration(runner)  # warm-up
        times = [timed_iteration(runner) for _ in range(args.iterations)]
        collect = statistics.median(t[0] for t in times)
        learn = statistics.median(t[1] for t in times)
        steps = n * cfg.runner.num_steps_per_env
        bare = bare_physics_rate(runner.env, cfg.runner.num_steps_per_env, args.threads)
        loop = steps / (collect + learn)
        print(f"{n:>6}{collect:>11.2f}{learn:>9.2f}{steps / collect:>11.0f}{loop:>9.0f}{bare:>9.0f}{loop / bare:>11.2f}",
              flush=True)


if __name__ == "__main__":
    main()
