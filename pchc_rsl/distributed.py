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
