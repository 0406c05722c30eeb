"""The real training loop on a GPU: ``runner.learn`` on MuJoCo Warp, timed, with the physics' peaks and host syncs.

    python tools/gpu_learn_check.py --num-envs 4096 8192 [--iterations 3] [--task g1-walk-fast] [--motion-files ...]

For each N: a fresh PCHC runner on the task (as pchc-train builds it, symmetry and AMP as configured) runs
``runner.learn`` for --iterations; printed: the median iteration time after the first (which captures the CUDA graphs
and compiles), env steps per second, collection and learning seconds, the largest constraint rows of a world, the
largest solver iteration count and contacts (Warp's buffers, read once per iteration; an overflow stops the run),
and the host syncs of one rollout counted by torch's sync debug mode, per env step. Exits 1 on any failure.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
import warnings

import torch

from pchc_rsl.configs import task_config
from pchc_rsl.training.build import make_runner


def count_syncs_of_second_rollout(runner, counts: list) -> None:
    """Wrap runner.rollout: the second rollout of learn (graphs captured by then) runs under torch's sync debug mode,
    and the host syncs it reports are appended to ``counts``."""
    rollout, calls = runner.rollout, []

    def counted(obs):
        calls.append(1)
        if len(calls) != 2:
            return rollout(obs)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            torch.cuda.set_sync_debug_mode("warn")
            try:
                return rollout(obs)
            finally:
                torch.cuda.set_sync_debug_mode("default")
                counts.append(sum("synchroniz" in str(w.message) for w in caught))

    runner.rollout = counted


def check(task: str, num_envs: int, iterations: int, device: str, motion_files: list[str] | None) -> dict:
    cfg = task_config(task)
    cfg.num_envs, cfg.device, cfg.env.physics = num_envs, device, "warp"
    cfg.runner.max_iterations = iterations
    if motion_files:
        cfg.runner.algorithm.amp_cfg.motion_files = list(motion_files)
    with tempfile.TemporaryDirectory() as log_dir:
        start = time.perf_counter()
        runner = make_runner(cfg, log_dir)
        built = time.perf_counter() - start
        times = []
        log = runner.logger.log

        def timed_log(**kwargs):
            times.append((kwargs["collect_time"], kwargs["learn_time"]))
            log(**kwargs)

        runner.logger.log = timed_log
        syncs: list[int] = []
        count_syncs_of_second_rollout(runner, syncs)
        runner.learn(iterations)
        physics = dict(runner.logger.physics_stats)
    syncs_per_step = syncs[0] / cfg.runner.num_steps_per_env if syncs else float("nan")
    steady = times[1:] or times
    collect = statistics.median(t[0] for t in steady)
    learn = statistics.median(t[1] for t in steady)
    steps = num_envs * cfg.runner.num_steps_per_env
    return {"built_s": built, "first_s": sum(times[0]), "collect_s": collect, "learn_s": learn,
            "steps_per_s": steps / (collect + learn), "syncs_per_step": syncs_per_step, **physics}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="g1-walk-fast")
    parser.add_argument("--num-envs", type=int, nargs="+", default=[4096, 8192])
    parser.add_argument("--iterations", type=int, default=3,
                        help="learning iterations per N, at least 2 (the first captures the graphs)")
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--motion-files", nargs="+", metavar="PATH", help="AMP reference motions (AMP off without)")
    args = parser.parse_args(argv)
    if args.iterations < 2:
        parser.error(f"--iterations must be >= 2 (the first captures the CUDA graphs), got {args.iterations}")
    if not torch.cuda.is_available():
        print("gpu_learn_check: torch sees no CUDA device; run tools/gpu_preflight.py", flush=True)
        return 1
    print(f"gpu_learn_check: {args.task}, Warp on {args.device} ({torch.cuda.get_device_name(args.device)}), AMP "
          f"{'on' if args.motion_files else 'off'}, {args.iterations} iterations per N", flush=True)
    for n in args.num_envs:
        r = check(args.task, n, args.iterations, args.device, args.motion_files)
        print(f"N {n}: {r['steps_per_s']:,.0f} env steps/s (collect {r['collect_s']:.2f} s, learn {r['learn_s']:.2f} s "
              f"per iteration; first iteration {r['first_s']:.1f} s, build {r['built_s']:.1f} s); host syncs "
              f"{r['syncs_per_step']:.2f} per env step; peaks: {r['max_constraint_rows']:.0f} of "
              f"{r['constraint_rows_capacity']:.0f} constraint rows, {r['max_solver_iterations']:.0f} of "
              f"{r['solver_iterations_limit']:.0f} solver iterations, {r['max_contacts']:.0f} of "
              f"{r['contacts_capacity']:.0f} contacts", flush=True)
        torch.cuda.empty_cache()
    return 0


if __name__ == "__main__":
    sys.exit(main())
