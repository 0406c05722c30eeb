"""Whole training loop against bare physics: where an iteration's time goes, and how close it gets to the limit.

    python tools/bench_train.py [--num-envs 256 1024 4096] [--iterations 2] [--threads 1]

For each N, in the same process: a PCHC runner on the task (randomised envs, as in training) runs warm-up and
timed iterations of rsl-rl's loop (rollout of num_steps_per_env steps: act, env.step, process_env_step; then
compute_returns and the PPO update), collection and learning timed apart. Two physics limits of the same model
variants and thread count, BatchedMuJoCo.step alone for as many policy steps: "standing" from standing states at
the default pose (robots at rest: the cheapest contacts), and "replay" from the rollout's own start states with the
controls the policy sent (the physics work training really asked for). Prints env steps per second of collection,
of the whole loop, of both limits, and the ratios whole loop / limit.
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from pchc_rsl.cli.common import make_runner
from pchc_rsl.configs import task_config
from pchc_rsl.envs.physics import BatchedMuJoCo


def timed_iteration(runner, record: list | None = None) -> tuple[float, float]:
    """One iteration of OnPolicyRunner.learn's body; (collection s, learning s). With ``record``, appends the
    physics state at the start and every control the env sent to the physics."""
    alg, env = runner.alg, runner.env
    if record is not None:
        record.append(env.physics.state.copy())
        step = env.physics.step
        env.physics.step = lambda ctrl: (record.append(ctrl.copy()), step(ctrl))[1]
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
    if record is not None:
        del env.physics.step  # back to the class' method
    return collected - start, time.perf_counter() - collected


def replay_rate(env, record: list, threads: int) -> float:
    """Bare physics from the recorded start state with the recorded controls: [N] env steps per second."""
    physics = env.physics
    bare = BatchedMuJoCo(physics.models, env.num_envs, physics.substeps, threads)
    bare.state[:] = record[0]
    start = time.perf_counter()
    for ctrl in record[1:]:
        bare.step(ctrl)
    return env.num_envs * (len(record) - 1) / (time.perf_counter() - start)


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
    print(f"{'N':>6}{'collect s':>11}{'learn s':>9}{'collect/s':>11}{'loop/s':>9}{'standing/s':>12}{'replay/s':>10}"
          f"{'loop/standing':>15}{'loop/replay':>13}")
    for n in args.num_envs:
        cfg = task_config(args.task)
        cfg.num_envs, cfg.device = n, args.device
        cfg.env.num_threads = args.threads
        runner = make_runner(cfg)
        runner.alg.train_mode()
        timed_iteration(runner)  # warm-up
        record: list = []
        times = [timed_iteration(runner, record if i == 0 else None) for i in range(args.iterations)]
        collect = statistics.median(t[0] for t in times)
        learn = statistics.median(t[1] for t in times)
        steps = n * cfg.runner.num_steps_per_env
        replay = replay_rate(runner.env, record, args.threads)
        standing = bare_physics_rate(runner.env, cfg.runner.num_steps_per_env, args.threads)
        loop = steps / (collect + learn)
        print(f"{n:>6}{collect:>11.2f}{learn:>9.2f}{steps / collect:>11.0f}{loop:>9.0f}{standing:>12.0f}{replay:>10.0f}"
              f"{loop / standing:>15.2f}{loop / replay:>13.2f}", flush=True)


if __name__ == "__main__":
    main()
