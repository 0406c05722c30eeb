"""Training curves of one or more runs against env steps and against wall-clock time, from their TensorBoard events.

    python tools/plot_training.py logs/run-a logs/run-b --tags Train/mean_reward Episode_Termination/fall \
        --out curves.png

The question a change to the training loop must answer is whether it learns faster per hour, not per step: each
tag gets two panels, value against env steps and value against wall-clock hours. A resumed run is read from all its
folders in order (give them joined by '+': logs/run-a+logs/run-a-more), its clock and steps continuing;
'folder@N' keeps that folder's iterations up to N (a branch resumed from its model_N.pt while the folder's own run
went on). Without '@', a folder's iterations that the next folder logs again (it was resumed from an earlier
checkpoint of this one) are counted once, as the next folder's; a next folder that starts at iteration 0 (trained
with --init-from) follows all of this one. Prints, per run and tag, the last value (mean of the last 5 points), the
env steps and the hours it took.
"""

from __future__ import annotations

import argparse
import glob
import json
import os

import numpy as np


def read_scalars(folder: str, tag: str) -> tuple[np.ndarray, np.ndarray]:
    """(iterations, values) of ``tag`` in a run folder's event files, ordered by iteration."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

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
    parts = [part.partition("@")[::2] for part in spec.split("+")]
    timed = [read_scalars(folder, "Perf/collection_time") for folder, _ in parts]
    for index, ((folder, until), (its, seconds)) in enumerate(zip(parts, timed)):
        iterations, values = read_scalars(folder, tag)
        _, learning = read_scalars(folder, "Perf/learning_time")
        following = timed[index + 1][0] if index + 1 < len(timed) else []
        if not until and len(following) and len(its) and 0 < following[0] <= its[-1]:
            until = str(following[0] - 1)  # resumed from an earlier checkpoint, the next folder redid these iterations
        if until:
            last = int(until)
            iterations, values = iterations[iterations <= last], values[iterations <= last]
            seconds, learning = seconds[its <= last], learning[: len(its)][its <= last]
            its = its[its <= last]
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


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", help="run folders (a resumed run: folders joined by '+')")
    parser.add_argument("--tags", nargs="+", default=["Train/mean_reward", "Episode_Termination/fall"])
    parser.add_argument("--labels", nargs="+", help="one label per run (default: the folder names)")
    parser.add_argument("--smooth", type=int, default=20, help="moving-average window in points")
    parser.add_argument("--out", default="training_curves.png")
    args = parser.parse_args(argv)
    labels = args.labels or [os.path.basename(spec.split("+")[0].rstrip("/")) for spec in args.runs]
    if len(labels) != len(args.runs):
        raise SystemExit(f"plot_training: {len(args.runs)} runs but {len(labels)} labels.")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(args.tags), 2, figsize=(10, 3.2 * len(args.tags)), squeeze=False)
    print(f"{'run':<24}{'tag':<36}{'last':>10}{'env steps':>14}{'hours':>8}")
    for spec, label in zip(args.runs, labels):
        for row, tag in enumerate(args.tags):
            steps, hours, values = run_curves(spec, tag)
            if len(values) == 0:
                print(f"{label:<24}{tag:<36}{'-':>10}")
                continue
            window = max(1, min(args.smooth, len(values)))
            smooth = np.convolve(values, np.ones(window) / window, mode="valid")
            axes[row, 0].plot(steps[window - 1 :], smooth, label=label)
            axes[row, 1].plot(hours[window - 1 :], smooth, label=label)
            print(f"{label:<24}{tag:<36}{values[-5:].mean():>10.4g}{steps[-1]:>14,}{hours[-1]:>8.2f}")
    for row, tag in enumerate(args.tags):
        axes[row, 0].set_ylabel(tag, fontsize=8)
        axes[row, 0].set_xlabel("env steps")
        axes[row, 1].set_xlabel("wall-clock hours")
        axes[row, 1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(args.out, dpi=90)
    print(f"plot_training: wrote {args.out}")


if __name__ == "__main__":
    main()
