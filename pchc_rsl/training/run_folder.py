"""The folder a training run writes into: always a new one, so no run overwrites another run's files."""

from __future__ import annotations

import datetime
import glob
import os
import shutil


def new_run_folder(log_dir: str | None, task: str) -> str:
    """``log_dir`` if it does not exist yet or is empty; by default a fresh ``logs/<task>/<date>``.

    Raises ValueError for a folder that already holds files (another run's checkpoints or events)."""
    if log_dir is None:
        base = os.path.join("logs", task, datetime.datetime.now().strftime("%Y-%m-%d_%H-%M-%S"))
        path, n = base, 1
        while os.path.exists(path):
            path, n = f"{base}_{n}", n + 1
        return path
    if os.path.exists(log_dir):
        if not os.path.isdir(log_dir):
            raise ValueError(f"--log-dir {log_dir} is a file, not a folder.")
        held = sorted(os.listdir(log_dir))
        if held:
            shown = ", ".join(held[:3]) + (", ..." if len(held) > 3 else "")
            raise ValueError(
                f"--log-dir {log_dir} already holds {shown}: a run never writes into another run's folder; "
                "give a new --log-dir (or leave it out for logs/<task>/<date>)."
            )
    return log_dir


def checkpoints_in(folder: str) -> list[str]:
    """``model_<it>.pt`` files of a run folder, by iteration."""
    paths = glob.glob(os.path.join(folder, "model_*.pt"))
    return sorted(paths, key=lambda p: int(os.path.basename(p)[6:-3]) if os.path.basename(p)[6:-3].isdigit() else -1)


def first_missing_folder(path: str) -> str | None:
    """The outermost folder of ``path`` that does not exist yet (what a run creates), None if ``path`` exists."""
    path = os.path.abspath(path)
    missing = None
    while not os.path.exists(path):
        missing, path = path, os.path.dirname(path)
    return missing


def remove_if_unused(folder: str, created: str | None) -> None:
    """After a failed run: if it wrote no checkpoint, remove what it wrote: the folders it created (``created``,
    from first_missing_folder before the run), or the contents of an empty folder it was given."""
    if not os.path.isdir(folder) or checkpoints_in(folder):
        return
    if created is not None:
        shutil.rmtree(created, ignore_errors=True)
        return
    for name in os.listdir(folder):
        path = os.path.join(folder, name)
        shutil.rmtree(path) if os.path.isdir(path) else os.remove(path)
