"""How many CPU threads training uses: MuJoCo's physics threads while collecting, torch's while learning.

The two never run at once (each policy step runs the physics, then the networks), so both get the same count,
by default the cores this process may use, shared out among the training processes torchrun started on this
machine; more would oversubscribe the cores and slow every thread down.
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
    threads = threads or max(1, cores // processes)
    torch.set_num_threads(threads)
    physics = hasattr(cfg.env, "num_threads")
    if physics:
        cfg.env.num_threads = threads
    where = "MuJoCo physics threads while collecting, torch threads while learning" if physics else "torch threads"
    share = f", {processes} processes" if processes > 1 else ""
    warning = f" (more than the {cores} cores available: expect slowdowns)" if threads * processes > cores else ""
    return f"threads: {threads} of {cores} cores{share} ({where}){warning}"
