"""The cells of a benchmark study (tools/studies): each one training run of tools/studies/mo_benchmark.py in its own
folder under the study's root, shared among workers by lock files; and the training folders and checkpoints such a
run folder holds."""

from __future__ import annotations

import os
import re
import shutil
from dataclasses import dataclass, field


@dataclass
class Cell:
    """One run of a study: its group of cells, task, name (the variant and setting), seed and benchmark arguments."""

    group: str
    task: str
    name: str
    seed: int
    args: list[str] = field(default_factory=list)

    def folder(self, root: str) -> str:
        return os.path.join(root, self.task, f"{self.name}_seed{self.seed}")


def claim_cell(folder: str, restart: bool = True) -> bool:
    """Take the cell for this process: False when it is finished or a live worker holds it.

    The claim is ``<folder>.claim`` holding the worker's pid, linked into place whole (so two workers cannot both
    win, and no one reads it half-written); a claim whose pid is gone is a worker that was stopped, and its
    half-written folder is cleared, unless ``restart`` is False (the run resumes from what it left).
    """
    claim = folder + ".claim"
    os.makedirs(os.path.dirname(folder), exist_ok=True)
    mine = f"{claim}.{os.getpid()}"
    with open(mine, "w") as f:
        f.write(str(os.getpid()))
    try:
        while not os.path.isfile(os.path.join(folder, "result.json")):
            try:
                os.link(mine, claim)
            except FileExistsError:
                if process_alive(read_pid(claim)):
                    return False
                os.remove(claim)  # a stopped worker's claim
                continue
            if restart and os.path.isdir(folder):  # interrupted before its result.json: start again from scratch
                shutil.rmtree(folder)
            os.makedirs(folder, exist_ok=True)
            return True
        return False
    finally:
        os.remove(mine)


def read_pid(path: str) -> int:
    try:
        with open(path) as f:
            return int(f.read().strip() or 0)
    except (OSError, ValueError):
        return 0


def process_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def train_folders(out: str) -> list[str]:
    """A run's training folders in the order they were written: train, then train_resumed1, 2, ... (a resumed run
    trains into a new folder, as pchc-train --resume does)."""
    resumed = sorted((int(m.group(1)), name) for name in (os.listdir(out) if os.path.isdir(out) else [])
                     if (m := re.fullmatch(r"train_resumed(\d+)", name)))
    return [os.path.join(out, "train")] + [os.path.join(out, name) for _, name in resumed]


def run_checkpoints(out: str) -> dict[int, str]:
    """iteration -> the newest model_<iteration>.pt among the run's training folders."""
    found = {}
    for folder in train_folders(out):
        for name in os.listdir(folder) if os.path.isdir(folder) else []:
            if m := re.fullmatch(r"model_(\d+)\.pt", name):
                found[int(m.group(1))] = os.path.join(folder, name)
    return found
