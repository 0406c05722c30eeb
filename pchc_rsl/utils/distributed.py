"""Several training processes (torchrun): each rank its own envs and seed, gradients averaged, rank 0 logs.

rsl-rl's multi-GPU path sets up NCCL on ``cuda:LOCAL_RANK``; on CPUs the same scheme runs over Gloo. torchrun
sets WORLD_SIZE, RANK and LOCAL_RANK (and the rendezvous address) for every process it starts.
"""

from __future__ import annotations

import os

import torch


class DistributedSetupError(RuntimeError):
    """The multi-process world could not start; the message says what is missing."""


def world() -> tuple[int, int, int]:
    """(world size, global rank, local rank) of this process; (1, 0, 0) outside torchrun."""
    return int(os.getenv("WORLD_SIZE", "1")), int(os.getenv("RANK", "0")), int(os.getenv("LOCAL_RANK", "0"))


def init_process_group(backend: str, rank: int, world_size: int) -> None:
    """Join the torchrun world, or fail in one line that says what is missing."""
    if torch.distributed.is_initialized():
        return
    if not torch.distributed.is_available() or not getattr(torch.distributed, f"is_{backend}_available")():
        raise DistributedSetupError(f"this torch build has no {backend} backend for multi-process training; "
                           + ("install a CUDA build of torch" if backend == "nccl" else "install a torch with Gloo")
                           + " or train in one process.")
    try:
        torch.distributed.init_process_group(backend=backend, rank=rank, world_size=world_size)
    except Exception as error:  # noqa: BLE001 - any failure to rendezvous means the same thing to the user
        first = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        raise DistributedSetupError(f"could not start the {world_size}-process {backend} world as rank {rank} ({first}); "
                           "start training with torchrun, e.g. torchrun --standalone --nproc_per_node=2 -m "
                           "pchc_rsl.cli.train --task ...") from None


def bind_local_gpu(device: str) -> str:
    """Under torchrun on CUDA: make the GPU of this process' local rank the current one, before anything (the env,
    Warp's physics, the networks) allocates on a GPU, and return it ("cuda:LOCAL_RANK"); otherwise ``device``."""
    world_size, _, local_rank = world()
    if world_size <= 1 or torch.device(device).type != "cuda":
        return device
    torch.cuda.set_device(local_rank)
    return f"cuda:{local_rank}"


def shutdown_process_group() -> None:
    """Leave the torchrun world (torch warns, and NCCL may hang at exit, when a process ends without it)."""
    if torch.distributed.is_available() and torch.distributed.is_initialized():
        torch.distributed.destroy_process_group()
