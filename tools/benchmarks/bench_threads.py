"""CPU training beside another torch process: wall time of a short training run on a quiet machine and beside one
pchc-eval, per thread setting, as ratios.

    python tools/benchmarks/bench_threads.py                       # toy and g1-walk-fast, every setting, 2 repeats
    python tools/benchmarks/bench_threads.py --tasks toy --repeats 3

Why: torch's OpenMP threads spin while they wait for work. Two torch processes that each use every core then take
turns spinning on each other's cores, and a training run that took 10 s alone took 88 s beside one pchc-eval. Each
setting runs pchc-train in a fresh process (the environment variables must be set before torch loads OpenMP):
``default`` as pchc-train runs now (physics on every core, torch on one), ``a thread per core`` torch's own default,
``passive wait`` the same with OMP_WAIT_POLICY=PASSIVE (idle OpenMP threads sleep), ``threads=1``. "beside" starts a pchc-eval of the shipped walker first and stops it after the
run. Prints seconds (median of the repeats) and beside / quiet for each setting and task.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RUNS = {
    "toy": ["--task", "toy", "--num-envs", "64", "--max-iterations", "20"],
    "g1-walk-fast": ["--task", "g1-walk-fast", "--num-envs", "128", "--max-iterations", "4"],
}
CORES = len(os.sched_getaffinity(0))
SETTINGS = {
    "default": ({}, []),
    "a thread per core": ({}, ["--threads", str(CORES)]),
    "passive wait": ({"OMP_WAIT_POLICY": "PASSIVE"}, ["--threads", str(CORES)]),
    "threads=1": ({}, ["--threads", "1"]),
}
"""name -> (environment variables, None: unset; pchc-train flags). ``a thread per core`` is torch's own default (torch
and physics on every core); ``default`` the physics on every core and torch on one. The pchc-eval beside runs with
the same variables and its own default threads."""


def environment(env_vars: dict) -> dict:
    env = {**os.environ, **{k: v for k, v in env_vars.items() if v is not None}}
    for key in [k for k, v in env_vars.items() if v is None]:
        env.pop(key, None)
    return env


def train_seconds(task: str, env_vars: dict, flags: list[str]) -> float:
    with tempfile.TemporaryDirectory() as folder:
        command = [sys.executable, "-m", "pchc_rsl.cli.train", *RUNS[task], *flags, "--log-dir", f"{folder}/run"]
        env = environment(env_vars)
        start = time.perf_counter()
        subprocess.run(command, check=True, env=env, stdout=subprocess.DEVNULL, cwd=ROOT)
        return time.perf_counter() - start


def beside_eval(task: str, env_vars: dict, flags: list[str]) -> float:
    """The same run while a pchc-eval of the shipped walker (its own default threads) keeps the cores busy."""
    with tempfile.TemporaryDirectory() as folder:
        load = subprocess.Popen(
            [sys.executable, "-m", "pchc_rsl.cli.eval", os.path.join(ROOT, "policies", "g1_walk.pt"), "--num-envs",
             "128", "--episodes", "50", "--output", f"{folder}/eval"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT, env=environment(env_vars))
        try:
            time.sleep(8.0)  # past its imports: evaluating
            return train_seconds(task, env_vars, flags)
        finally:
            load.terminate()
            load.wait()


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", nargs="+", default=list(RUNS), choices=list(RUNS))
    parser.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=list(SETTINGS))
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args(argv)
    rows = {}
    print(f"cores: {len(os.sched_getaffinity(0))}; seconds are medians of {args.repeats} runs")
    print("| task | setting | quiet (s) | beside pchc-eval (s) | beside / quiet |")
    print("|---|---|---|---|---|")
    for task in args.tasks:
        for name in args.settings:
            env_vars, flags = SETTINGS[name]
            quiet = statistics.median(train_seconds(task, env_vars, flags) for _ in range(args.repeats))
            busy = statistics.median(beside_eval(task, env_vars, flags) for _ in range(args.repeats))
            rows[(task, name)] = (quiet, busy)
            print(f"| {task} | {name} | {quiet:.1f} | {busy:.1f} | {busy / quiet:.2f} |", flush=True)
    return rows


if __name__ == "__main__":
    main()
