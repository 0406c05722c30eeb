"""The real training loop on a GPU: ``runner.learn`` on MuJoCo Warp, timed, with the physics' peaks and host syncs.

    python tools/gpu/gpu_learn_check.py --num-envs 4096 8192 [--iterations 10] [--task g1-walk-fast]
        [--motion-files ...] [--json PATH]

For each N: a fresh PCHC runner on the task (as pchc-train builds it, symmetry and AMP as configured) runs
``runner.learn`` for --iterations. Printed and written: the median iteration time after the first (which captures
the CUDA graphs and compiles), env steps per second, collection and learning seconds; Warp's peaks over the run
(constraint rows of a world, contacts, solver iterations, the share of world-steps whose solver stopped at its
limit; an overflow fails); the host syncs of one rollout counted by torch's sync debug mode, per env step, with the
lines that made them; and env.step against physics.step alone (the same control, graphs captured): the share of a
step the env's own torch work leaves to the physics (1 = none). Exits 1 on any failure. --device cpu runs the same
on Warp's CPU device without counting syncs (a smoke test of the tool).
"""

from __future__ import annotations

import argparse
import collections
import json
import statistics
import sys
import tempfile
import time
import warnings

import torch

from pchc_rsl.configs import task_config
from pchc_rsl.training.build import make_runner


def count_syncs_of_second_rollout(runner, counts: list, sites: collections.Counter) -> None:
    """Wrap runner.rollout: the second rollout of learn (graphs captured by then) runs under torch's sync debug mode;
    the host syncs it reports are appended to ``counts`` and counted by the line of Python that made them."""
    rollout, calls = runner.rollout, []

    def counted(obs):
        calls.append(1)
        if len(calls) != 2 or not torch.cuda.is_available():
            return rollout(obs)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            torch.cuda.set_sync_debug_mode("warn")
            try:
                return rollout(obs)
            finally:
                torch.cuda.set_sync_debug_mode("default")
                syncs = [w for w in caught if "synchroniz" in str(w.message)]
                counts.append(len(syncs))
                sites.update(f"{w.filename.rsplit('/', 2)[-2]}/{w.filename.rsplit('/', 1)[-1]}:{w.lineno}"
                             for w in syncs)

    runner.rollout = counted


def synchronize(device: str) -> None:
    if torch.device(device).type == "cuda":
        torch.cuda.synchronize(device)


def step_ratio(env, steps: int = 50) -> dict:
    """Seconds per env.step and per physics.step alone with the same held control, and their ratio."""
    actions = torch.zeros(env.num_envs, env.num_actions, device=env.device)
    control = env.default_joint_pos.expand(env.num_envs, -1).to(env.physics.qpos.dtype)
    times = {}
    with torch.inference_mode():
        for name, call in (("env", lambda: env.step(actions)), ("physics", lambda: env.physics.step(control))):
            for _ in range(3):
                call()
            synchronize(env.device)
            start = time.perf_counter()
            for _ in range(steps):
                call()
            synchronize(env.device)
            times[name] = (time.perf_counter() - start) / steps
    env.physics_report()  # the held control may have left robots on the floor: the peaks of training stay apart
    return {"env_step_s": times["env"], "physics_step_s": times["physics"],
            "env_over_physics": times["physics"] / times["env"]}


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
        times, peaks = [], collections.defaultdict(float)
        log = runner.logger.log

        def timed_log(**kwargs):
            times.append((kwargs["collect_time"], kwargs["learn_time"]))
            for key, value in runner.logger.physics_stats.items():
                peaks[key] = max(peaks[key], value)
            log(**kwargs)

        runner.logger.log = timed_log
        syncs: list[int] = []
        sites: collections.Counter = collections.Counter()
        count_syncs_of_second_rollout(runner, syncs, sites)
        runner.learn(iterations)
        ratio = step_ratio(runner.env)
    steady = times[1:] or times
    collect = statistics.median(t[0] for t in steady)
    learn = statistics.median(t[1] for t in steady)
    steps = num_envs * cfg.runner.num_steps_per_env
    return {"task": task, "num_envs": num_envs, "iterations": iterations, "amp": bool(motion_files),
            "built_s": built, "first_s": sum(times[0]), "collect_s": collect, "learn_s": learn,
            "steps_per_s": steps / (collect + learn),
            "syncs_per_step": syncs[0] / cfg.runner.num_steps_per_env if syncs else None,
            "sync_sites": dict(sites.most_common(10)), **ratio, "physics": dict(peaks)}


def line(r: dict) -> str:
    p = r["physics"]
    syncs = "not counted (no CUDA)" if r["syncs_per_step"] is None else f"{r['syncs_per_step']:.2f} per env step"
    return (f"{r['task']} N {r['num_envs']}: {r['steps_per_s']:,.0f} env steps/s (collect {r['collect_s']:.2f} s, "
            f"learn {r['learn_s']:.2f} s per iteration; first iteration {r['first_s']:.1f} s, build "
            f"{r['built_s']:.1f} s); host syncs {syncs}; env.step at {r['env_over_physics']:.2f} of physics.step "
            f"({1e3 * r['env_step_s']:.1f} against {1e3 * r['physics_step_s']:.1f} ms); peaks: "
            f"{p['max_constraint_rows']:.0f} of {p['constraint_rows_capacity']:.0f} constraint rows, "
            f"{p['max_contacts']:.0f} of {p['contacts_capacity']:.0f} contacts, {p['max_solver_iterations']:.0f} of "
            f"{p['solver_iterations_limit']:.0f} solver iterations, at the limit in {p['solver_limit_share']:.1f}% "
            f"of world-steps (worst iteration)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="g1-walk-fast")
    parser.add_argument("--num-envs", type=int, nargs="+", default=[4096, 8192])
    parser.add_argument("--iterations", type=int, default=10,
                        help="learning iterations per N, at least 2 (the first captures the graphs)")
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--motion-files", nargs="+", metavar="PATH", help="AMP reference motions (AMP off without)")
    parser.add_argument("--json", metavar="PATH", help="write the results here")
    args = parser.parse_args(argv)
    if args.iterations < 2:
        parser.error(f"--iterations must be >= 2 (the first captures the CUDA graphs), got {args.iterations}")
    cuda = torch.device(args.device).type == "cuda"
    if cuda and not torch.cuda.is_available():
        print("gpu_learn_check: torch sees no CUDA device; run tools/gpu/gpu_preflight.py", flush=True)
        return 1
    where = torch.cuda.get_device_name(args.device) if cuda else "Warp's CPU device"
    print(f"gpu_learn_check: {args.task}, Warp on {args.device} ({where}), AMP {'on' if args.motion_files else 'off'}, "
          f"{args.iterations} iterations per N", flush=True)
    results, failure = [], None
    for n in args.num_envs:
        try:
            r = check(args.task, n, args.iterations, args.device, args.motion_files)
        except Exception as error:  # noqa: BLE001 - reported in the summary, the check goes on to say so
            failure = f"{args.task} N {n}: {type(error).__name__}: {str(error).splitlines()[0][:400]}"
            print(f"gpu_learn_check: FAILED {failure}", flush=True)
            results.append({"task": args.task, "num_envs": n, "error": failure})
            break
        results.append(r)
        print(line(r), flush=True)
        if r["sync_sites"]:
            print("  syncs by line: " + ", ".join(f"{site} x{count}" for site, count in r["sync_sites"].items()),
                  flush=True)
        if cuda:
            torch.cuda.empty_cache()
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"task": args.task, "device": args.device, "results": results, "failure": failure}, f, indent=2)
    return 1 if failure else 0


if __name__ == "__main__":
    sys.exit(main())
