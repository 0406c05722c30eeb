"""Whole training loop against bare physics: where an iteration's time goes, and how close it gets to the limit.

    python tools/benchmarks/bench_train.py [--num-envs 256 1024 4096] [--iterations 2] [--threads 1]
    python tools/benchmarks/bench_train.py --physics warp --device cuda:0 --num-envs 4096   # on a GPU

For each N, in the same process: a PCHC runner on the task (randomised envs, as in training) runs warm-up and
timed iterations of rsl-rl's loop (rollout of num_steps_per_env steps: act, env.step, process_env_step; then
compute_returns and the PPO update), collection and learning timed apart; with ``--profile``, where each phase's time goes (cProfile, by own time). Two physics limits of the same model
variants and thread count (or device), the backend's step alone for as many policy steps: "standing" from standing
states at the default pose (robots at rest: the cheapest contacts), and "replay" from the rollout's own start states
with the controls the policy sent (the physics work training really asked for). Prints env steps per second of
collection, of the whole loop, of both limits, and the ratios whole loop / limit; ``--configs`` times config
variants side by side in the same run (e.g. fewer PPO epochs against the task's).
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from pchc_rsl.configs import task_config
from pchc_rsl.envs.physics.backend import make_physics
from pchc_rsl.training.build import make_runner
from pchc_rsl.training.checks import check_device, check_physics
from pchc_rsl.training.overrides import apply_overrides


def sync(device: str) -> None:
    """Wait for the GPU's queued work, so that wall-clock times mean something there."""
    if torch.device(device).type == "cuda":
        torch.cuda.synchronize(device)


def timed_iteration(runner, record: list | None = None) -> tuple[float, float]:
    """One iteration of PCHCRunner.learn's body (without writing logs); (collection s, learning s). With ``record``, appends the
    joint state (qpos, qvel) at the start and every control the env sent to the physics."""
    alg, env = runner.alg, runner.env
    if record is not None:
        record.append((env.physics.qpos.clone(), env.physics.qvel.clone()))
        step = env.physics.step
        env.physics.step = lambda ctrl: (record.append(ctrl.clone()), step(ctrl))[1]
    obs = env.get_observations().to(runner.device)
    sync(runner.device)
    start = time.perf_counter()
    obs = runner.rollout(obs)  # the loop's own rollout: act, env step, storage, NaN check, episode book-keeping
    sync(runner.device)
    collected = time.perf_counter()
    with torch.inference_mode():
        alg.compute_returns(obs)
    alg.update()
    runner.logger.flush_finished_episodes()
    runner.logger.ep_extras.clear()
    sync(runner.device)
    if record is not None:
        del env.physics.step  # back to the class' method
    return collected - start, time.perf_counter() - collected


def profile_iteration(runner, top: int) -> None:
    """One more iteration under cProfile, collection and learning apart: the ``top`` functions by own time, each
    phase's total, and the physics' share of collection."""
    import cProfile
    import pstats

    profiles = {"collection": cProfile.Profile(), "learning": cProfile.Profile()}
    obs = runner.env.get_observations()
    profiles["collection"].enable()
    obs = runner.rollout(obs)
    profiles["collection"].disable()
    profiles["learning"].enable()
    with torch.inference_mode():
        runner.alg.compute_returns(obs)
    runner.alg.update()
    profiles["learning"].disable()
    runner.logger.flush_finished_episodes()
    runner.logger.ep_extras.clear()
    for phase, profile in profiles.items():
        stats = pstats.Stats(profile)
        total = stats.total_tt
        print(f"-- {phase}: {total:.2f} s under the profiler; top {top} by own time (s, share, calls, function)")
        rows = sorted(stats.stats.items(), key=lambda item: item[1][2], reverse=True)[:top]
        for (filename, line, name), (_, calls, own, cumulative, _) in rows:
            where = f"{filename.rsplit('/', 2)[-2]}/{filename.rsplit('/', 1)[-1]}:{line}" if line else filename
            print(f"   {own:7.3f} {own / total:6.1%} {calls:>7} {name} ({where})")
        by_caller = {}
        for (filename, line, name), (_, _, own, cumulative, _) in stats.stats.items():
            for part in ("batched_mujoco.py", "g1/rewards.py", "g1/observations.py", "style.py", "discriminator.py",
                         "pci.py", "g1/symmetry.py", "multi_critic_ppo.py", "ppo.py", "g1/env.py"):
                if filename.endswith(part) and name in ("step", "compute", "groups", "push", "push_amp", "reward",
                                                        "update", "act", "process_env_step", "forward",
                                                        "augment_with_mirror", "compute_returns"):
                    by_caller[f"{part}:{name}"] = max(by_caller.get(f"{part}:{name}", 0.0), cumulative)
        shares = ", ".join(f"{k} {v:.2f} s" for k, v in sorted(by_caller.items(), key=lambda kv: -kv[1]))
        print(f"   inclusive: {shares}")


def bare_physics(env, threads: int):
    """A second physics of the env's backend, model variants and device, for the limits."""
    p = env.physics
    return make_physics(env.cfg.physics, p.models, env.num_envs, p.substeps, threads, p.device,
                        with_body_forces=p.body_forces is not None)


def stepping_rate(bare, controls: list) -> float:
    """[N] env steps per second of ``bare.step`` over these controls."""
    bare.step(controls[0])  # warm-up (Warp on a GPU: captures its CUDA graph)
    sync(bare.device)
    start = time.perf_counter()
    for ctrl in controls:
        bare.step(ctrl)
    sync(bare.device)
    return bare.num_envs * len(controls) / (time.perf_counter() - start)


def replay_rate(env, record: list, threads: int) -> float:
    """Bare physics from the recorded start state with the recorded controls: [N] env steps per second."""
    bare = bare_physics(env, threads)
    bare.set_qpos_qvel(torch.arange(env.num_envs, device=bare.device), *record[0])
    return stepping_rate(bare, record[1:])


def bare_physics_rate(env, steps: int, threads: int) -> float:
    """Bare physics holding the default pose from the env's reset states: [N] env steps per second."""
    bare = bare_physics(env, threads)
    with torch.inference_mode():  # the env's buffers are inference tensors once stepped in that mode
        env.reset()
    bare.set_qpos_qvel(torch.arange(env.num_envs, device=bare.device), env.physics.qpos, env.physics.qvel)
    ctrl = env.default_joint_pos.to(bare.qpos.dtype).expand(env.num_envs, -1).clone()
    return stepping_rate(bare, [ctrl] * steps)


def count_syncs(runner) -> int:
    """Host syncs torch reports in one iteration (rollout and update), from its sync debug mode's warnings."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        torch.cuda.set_sync_debug_mode("warn")
        try:
            timed_iteration(runner)
        finally:
            torch.cuda.set_sync_debug_mode("default")
    return sum("synchroniz" in str(w.message) for w in caught)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="g1-walk-fast")
    parser.add_argument("--num-envs", type=int, nargs="+", default=[256, 1024, 4096])
    parser.add_argument("--iterations", type=int, default=2, help="timed iterations (after one warm-up)")
    parser.add_argument("--threads", type=int, default=1, help="physics threads and torch threads")
    parser.add_argument("--device", default="cpu", help="torch device (Warp's physics runs there too)")
    parser.add_argument("--physics", choices=["mujoco", "warp"], default="mujoco")
    parser.add_argument("--motion-files", nargs="+", metavar="PATH",
                        help="AMP reference motions, as in training (without them the AMP update is not timed)")
    parser.add_argument("--profile", type=int, default=0, metavar="TOP",
                        help="also profile one iteration (cProfile) and print the TOP functions of each phase")
    parser.add_argument("--sync-debug", action="store_true",
                        help="on CUDA: also count the host syncs of one more iteration (torch's sync debug mode)")
    parser.add_argument("--configs", nargs="+", default=[""], metavar="'KEY=VALUE ...'",
                        help="config variants timed side by side, each a space-separated list of overrides ('' = "
                        "the task's), e.g. '' 'runner.algorithm.num_learning_epochs=2'")
    args = parser.parse_args()
    check_device(args.device)
    check_physics(args.physics)
    torch.set_num_threads(args.threads)
    print(f"{args.task}, {args.physics} physics, {args.threads} thread(s), device {args.device}, AMP "
          f"{'on' if args.motion_files else 'off'}; env steps/s; median of {args.iterations}")
    print(f"{'N':>6}{'collect s':>11}{'learn s':>9}{'collect/s':>11}{'loop/s':>9}{'standing/s':>12}{'replay/s':>10}"
          f"{'loop/standing':>15}{'loop/replay':>13}  config")
    for n in args.num_envs:
        for overrides in args.configs:
            cfg = task_config(args.task)
            cfg.num_envs, cfg.device = n, args.device
            cfg.env.num_threads, cfg.env.physics = args.threads, args.physics
            if args.motion_files:
                cfg.runner.algorithm.amp_cfg.motion_files = list(args.motion_files)
            apply_overrides(cfg, overrides.split())
            runner = make_runner(cfg)
            runner.alg.train_mode()
            runner.logger.writer = True  # as when training writes logs: the per-step episode book-keeping runs
            timed_iteration(runner)  # warm-up
            if args.profile:
                profile_iteration(runner, args.profile)
            record: list = []
            times = [timed_iteration(runner, record if i == 0 else None) for i in range(args.iterations)]
            collect = statistics.median(t[0] for t in times)
            learn = statistics.median(t[1] for t in times)
            steps = n * cfg.runner.num_steps_per_env
            replay = replay_rate(runner.env, record, args.threads)
            standing = bare_physics_rate(runner.env, cfg.runner.num_steps_per_env, args.threads)
            loop = steps / (collect + learn)
            if args.sync_debug and torch.device(args.device).type == "cuda":
                print(f"{n:>6}  host syncs in one iteration ({steps} env steps): {count_syncs(runner)}", flush=True)
            print(f"{n:>6}{collect:>11.2f}{learn:>9.2f}{steps / collect:>11.0f}{loop:>9.0f}{standing:>12.0f}"
                  f"{replay:>10.0f}{loop / standing:>15.2f}{loop / replay:>13.2f}  {overrides or 'task default'}",
                  flush=True)


if __name__ == "__main__":
    main()
