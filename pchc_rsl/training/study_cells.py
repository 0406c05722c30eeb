"""The cells of a benchmark study (tools/studies): each one training run of tools/studies/mo_benchmark.py in its own
folder under the study's root, shared among workers by lock files; and the training folders and checkpoints such a
run folder holds."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import time
from dataclasses import dataclass, field

import numpy as np


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


EVAL_EVERY = 250_000
"""The studies' evaluation grid (env steps)."""


def grid_point(env_steps: int, every: int = EVAL_EVERY) -> int:
    """The grid mark an evaluation belongs to: it ran after the first update at or past that mark."""
    return env_steps // every * every


def run_row(result: dict, every: int = EVAL_EVERY) -> dict:
    """One run of a study's JSON from its result.json: variant, seed, env steps, and each evaluation's env steps,
    measures and mean return per evaluation preference; the routing mass per expert over the last tenth of
    training (mixture actors)."""
    mass = result.get("routing_mass")
    last_tenth = None
    if mass:
        per_expert = np.array(mass["per_expert"])
        last_tenth = per_expert[:, -max(1, per_expert.shape[1] // 10):].mean(1).round(4).tolist()
    return {
        "variant": result["variant"], "seed": result["seed"], "env_steps": result["env_steps"],
        "evaluations": [{"env_steps": h["env_steps"], "grid_steps": grid_point(h["env_steps"], every),
                         "hypervolume": h["hypervolume"], "expected_utility": h["expected_utility"],
                         "mean_returns": h.get("mean_returns")}
                        for h in result["history"]],
        "preferences": result.get("preferences"),
        "parameters": result.get("parameters"), "expert_hidden_dims": result.get("expert_hidden_dims"),
        "routing_mass_last_tenth": last_tenth, "cpu_seconds": result.get("cpu_seconds"),
        "cpu_seconds_complete": result.get("cpu_seconds_complete", False), "resumed": result.get("resumed", 0),
    }


def run_figure(row: dict, measure: str, grid_steps) -> float | None:
    """Mean of a run's measure over these grid points; None when the run lacks one of them."""
    by_grid = {e["grid_steps"]: e[measure] for e in row["evaluations"]}
    if any(g not in by_grid for g in grid_steps):
        return None
    return float(np.mean([by_grid[g] for g in grid_steps]))


def run_cell(cell: Cell, root: str, command: list[str]) -> None:
    """Run one cell's ``command`` (a benchmark run into ``cell.folder(root)``, resumed where it was left) unless it
    is finished or another worker holds it; its output goes to the folder's log.txt."""
    folder = cell.folder(root)
    if not claim_cell(folder, restart=False):
        return
    start = time.time()
    try:
        with open(os.path.join(folder, "log.txt"), "a") as log:
            code = subprocess.call(command, stdout=log, stderr=subprocess.STDOUT)
    finally:
        if os.path.exists(folder + ".claim"):
            os.remove(folder + ".claim")
    status = "done" if code == 0 else f"FAILED (exit {code}, see {folder}/log.txt)"
    print(f"[{time.strftime('%H:%M:%S')}] {cell.name} seed {cell.seed}: {status} in {time.time() - start:.0f} s",
          flush=True)
