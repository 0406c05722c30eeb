"""How many CPU threads training uses: MuJoCo's physics threads while collecting, torch's while learning.

By default the physics gets the cores this process may use (shared out among the training processes torchrun started on
this machine) and torch one intra-op thread. The networks here are small (a few hundred units), so a second torch thread
buys little on a quiet machine (toy: 8.2 against 9.2 s), while torch's OpenMP threads spin while they wait, and two
torch processes with a thread per core take turns spinning on each other's cores: beside one pchc-eval the toy took 15x
its quiet time with a thread per core, and 0.95x with one (tools/benchmarks/bench_threads.py,
docs/results/training_speed.md). ``--threads N`` sets both to N.
"""

from __future__ import annotations

import os

import torch


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS reports it)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def apply_threads(cfg, threads: int | None) -> str:
    """Set torch's intra-op threads and, for envs with native physics threads, the env's; return a line to print."""
    cores = available_cores()
    processes = int(os.getenv("LOCAL_WORLD_SIZE", "1"))  # torchrun: the training processes on this machine
    physics_threads = threads or max(1, cores // processes)
    torch_threads = threads or 1
    torch.set_num_threads(torch_threads)
    physics = hasattr(cfg.env, "num_threads")
    if physics:
        cfg.env.num_threads = physics_threads
    share = f", {processes} processes" if processes > 1 else ""
    used = max(physics_threads if physics else 0, torch_threads)
    warning = f" (more than the {cores} cores available: expect slowdowns)" if used * processes > cores else ""
    where = (f"{physics_threads} MuJoCo physics while collecting, {torch_threads} torch while learning" if physics
             else f"{torch_threads} torch")
    return f"threads: {where}, of {cores} cores{share}{warning}"
