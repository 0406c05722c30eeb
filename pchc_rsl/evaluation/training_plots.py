"""Training curves of one or more runs against env steps and against wall-clock time, from their TensorBoard events.

The question a change to the training loop must answer is whether it learns faster per hour, not per step: each
tag gets two panels, value against env steps and value against wall-clock hours. A resumed run is read from all its
folders in order (given joined by '+': logs/run-a+logs/run-a-more), its clock and steps continuing; 'folder@N' keeps
that folder's iterations up to N (a branch resumed from its model_N.pt while the folder's own run went on). Without
'@', a folder's iterations that the next folder logs again (it was resumed from an earlier checkpoint of this one)
are counted once, as the next folder's; a next folder that starts at iteration 0 (trained with --init-from) follows
all of this one.
"""

from __future__ import annotations

import glob
import json
import os
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator


@dataclass(frozen=True)
class CurveSummary:
    """Where a run's curve of one tag ended: the last value (mean of the last 5 points), env steps and hours; None
    for a tag the run did not log."""

    label: str
    tag: str
    last: float | None = None
    env_steps: int | None = None
    hours: float | None = None


def run_parts(spec: str) -> list[tuple[str, int | None]]:
    """(folder, last iteration kept or None) of each part of a run given as 'folder[@N]+folder[@N]...'; ValueError
    naming the part for a folder without the run's config.json or an N that is not a whole number."""
    parts = []
    for part in spec.split("+"):
        folder, at, until = part.partition("@")
        if not os.path.isfile(os.path.join(folder, "config.json")):
            raise ValueError(f"run {spec}: {folder} is not a pchc-train run folder (no config.json); give run "
                             "folders, a resumed run's joined by '+'.")
        if at and not until.isdigit():
            raise ValueError(f"run {spec}: '{part}' keeps iterations up to N with folder@N, N a whole number.")
        parts.append((folder, int(until) if at else None))
    return parts


def read_scalars(folder: str, tag: str) -> tuple[np.ndarray, np.ndarray]:
    """(iterations, values) of ``tag`` in a run folder's event files, ordered by iteration."""
    steps, values = [], []
    for path in sorted(glob.glob(os.path.join(folder, "events.out.tfevents.*"))):
        events = EventAccumulator(path, size_guidance={"scalars": 0})
        events.Reload()
        if tag in events.Tags()["scalars"]:
            for event in events.Scalars(tag):
                steps.append(event.step)
                values.append(event.value)
    order = np.argsort(steps, kind="stable")
    return np.asarray(steps)[order], np.asarray(values)[order]


def env_steps_per_iteration(folder: str) -> int:
    with open(os.path.join(folder, "config.json")) as f:
        config = json.load(f)
    return int(config["num_envs"] * config["runner"]["num_steps_per_env"])


def run_curves(spec: str, tag: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(env steps, hours, values) of a run given as folders (each optionally 'folder@N') joined by '+', continuing
    steps and clock."""
    all_steps, all_hours, all_values = [], [], []
    steps_done, hours_done = 0, 0.0
    parts = run_parts(spec)
    timed = [read_scalars(folder, "Perf/collection_time") for folder, _ in parts]
    for index, ((folder, until), (its, seconds)) in enumerate(zip(parts, timed)):
        iterations, values = read_scalars(folder, tag)
        _, learning = read_scalars(folder, "Perf/learning_time")
        following = timed[index + 1][0] if index + 1 < len(timed) else []
        if until is None and len(following) and len(its) and 0 < following[0] <= its[-1]:
            until = following[0] - 1  # resumed from an earlier checkpoint, the next folder redid these iterations
        if until is not None:
            iterations, values = iterations[iterations <= until], values[iterations <= until]
            seconds, learning = seconds[its <= until], learning[: len(its)][its <= until]
            its = its[its <= until]
        if len(iterations) == 0 or len(its) == 0:
            continue
        clock = dict(zip(its, np.cumsum(seconds + learning[: len(seconds)]) / 3600.0))
        per_iteration = env_steps_per_iteration(folder)
        first = its[0]
        keep = [i for i, it in enumerate(iterations) if it in clock]
        all_steps.append(steps_done + (iterations[keep] - first + 1) * per_iteration)
        all_hours.append(hours_done + np.array([clock[iterations[i]] for i in keep]))
        all_values.append(values[keep])
        steps_done = int(all_steps[-1][-1]) if len(keep) else steps_done
        hours_done = float(all_hours[-1][-1]) if len(keep) else hours_done
    if not all_steps:
        return np.array([]), np.array([]), np.array([])
    return np.concatenate(all_steps), np.concatenate(all_hours), np.concatenate(all_values)


def plot_training(runs: list[str], tags: list[str], labels: list[str], out: str,
                  smooth: int = 20) -> list[CurveSummary]:
    """Draw each tag of each run (moving average over ``smooth`` points) against env steps and hours into ``out``;
    returns where each curve ended."""
    if len(labels) != len(runs):
        raise ValueError(f"--labels: {len(runs)} runs but {len(labels)} labels; give one label per run.")
    for spec in runs:
        run_parts(spec)  # every folder checked before any is read
    fig = Figure(figsize=(10, 3.2 * len(tags)))
    axes = fig.subplots(len(tags), 2, squeeze=False)
    summaries = []
    for spec, label in zip(runs, labels):
        for row, tag in enumerate(tags):
            steps, hours, values = run_curves(spec, tag)
            if len(values) == 0:
                summaries.append(CurveSummary(label, tag))
                continue
            window = max(1, min(smooth, len(values)))
            smoothed = np.convolve(values, np.ones(window) / window, mode="valid")
            axes[row, 0].plot(steps[window - 1 :], smoothed, label=label)
            axes[row, 1].plot(hours[window - 1 :], smoothed, label=label)
            summaries.append(CurveSummary(label, tag, float(values[-5:].mean()), int(steps[-1]), float(hours[-1])))
    for row, tag in enumerate(tags):
        axes[row, 0].set_ylabel(tag, fontsize=8)
        axes[row, 0].set_xlabel("env steps")
        axes[row, 1].set_xlabel("wall-clock hours")
        if axes[row, 1].lines:
            axes[row, 1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    return summaries


def summary_table(summaries: list[CurveSummary]) -> str:
    """The summaries as a fixed-width table: run, tag, last value, env steps, hours."""
    lines = [f"{'run':<24}{'tag':<36}{'last':>10}{'env steps':>14}{'hours':>8}"]
    for s in summaries:
        if s.last is None:
            lines.append(f"{s.label:<24}{s.tag:<36}{'-':>10}")
        else:
            lines.append(f"{s.label:<24}{s.tag:<36}{s.last:>10.4g}{s.env_steps:>14,}{s.hours:>8.2f}")
    return "\n".join(lines)
