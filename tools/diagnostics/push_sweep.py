"""Push strength against what the evaluation measures: per push speed and preference, the deviation after each push
and the share of episodes that stay up, under the task's mild preset with only the speed changed.

    python tools/diagnostics/push_sweep.py policies/g1_fall_recovery.pt --speeds 1.2 1.6 2.0 --num-envs 64
    python tools/diagnostics/push_sweep.py policies/g1_walk.pt --calibrate --plot walk_push_calibration.png

Why: the paper gives no push speed, only what its pushes did, so our presets are set by a rule on what they do
(``--calibrate``, at the middle preference (0.5, 0.5) of a fixed policy):
- mild: the speed whose deviation after a push (fall recovery: the COM; walking: the pelvis against the commanded
  path) comes closest to the paper's figure at (0.5, 0.5) (Table I: 1.62 m; Table II: 0.33 m) among the speeds
  that keep at least 90% of episodes up; if none reaches it, the strongest such speed;
- strong: the speed whose share of episodes that stay up comes closest to the paper's 75.7% (Table I, strong
  pushes at (0.5, 0.5)).
Prints a markdown table per metric (mean ± 95% half-width; rates with the Wilson interval) and the chosen speeds.
"""

from __future__ import annotations

import argparse

import numpy as np

from pchc_rsl.evaluation import aggregate, evaluation_config, evenly_spaced_preferences, loaded_policy, run_episodes
from pchc_rsl.evaluation import format_metric, task_config_of
from pchc_rsl.evaluation.plots import figure

PAPER_MIDDLE = {"fall": {"deviation": 1.62, "survival": 75.73}, "walk": {"deviation": 0.33, "survival": 75.73}}
"""The paper's figures at (0.5, 0.5): Table I's COM displacement and strong-push success, Table II's deviation."""


def task_keys(task: str) -> tuple[str, str, str]:
    """(family, deviation metric, survival metric) of a task."""
    if task.startswith("g1-walk"):
        return "walk", "push_deviation", "fall_rate"
    return "fall", "com_displacement", "success"


def survival(summary: dict, key: str) -> float:
    """Share of episodes (%) that stay up: success, or 100 - falls."""
    return summary[key] if key == "success" else 100.0 - summary[key]


def sweep(path: str, config: dict, speeds, preferences, num_envs: int, window_s: float | None, seed: int = 0):
    """{preference: {speed: aggregated metrics}} under the mild preset with this push speed (and window)."""
    out = {lam: {} for lam in preferences}
    for speed in speeds:
        overrides = [f"env.push.velocity={speed},{speed}"]
        if window_s is not None:
            overrides.append(f"env.push.window_s={window_s}")
        cfg = evaluation_config(config, "mild", num_envs, seed, overrides)
        runner, policy = loaded_policy(path, cfg)
        for lam in preferences:
            out[lam][speed] = aggregate(run_episodes(runner.env, policy, lam, 1)[0])
        print(f"push_sweep: {speed:g} m/s done", flush=True)
    return out


def choose_presets(results: dict, family: str, deviation_key: str, survival_key: str) -> tuple[float, float]:
    """The calibration rule of the module docstring, on one preference's {speed: metrics}."""
    target = PAPER_MIDDLE[family]
    speeds = sorted(results)
    safe = [s for s in speeds if survival(results[s], survival_key) >= 90.0]
    if not safe:
        raise SystemExit("push_sweep: no speed keeps 90% of episodes up; sweep weaker pushes.")
    mild = min(safe, key=lambda s: abs(results[s][deviation_key] - target["deviation"]))
    strong = min(speeds, key=lambda s: abs(survival(results[s], survival_key) - target["survival"]))
    return mild, strong


def print_tables(results: dict, speeds, deviation_key: str, survival_key: str) -> None:
    for key in (deviation_key, survival_key):
        print(f"\n{key}\n")
        print("| Preference | " + " | ".join(f"{s:g} m/s" for s in speeds) + " |")
        print("|---|" + "---|" * len(speeds))
        for lam, row in results.items():
            cells = (format_metric(row[s][key], row[s].get(f"{key}_ci95"), key, digits=3) for s in speeds)
            print(f"| ({lam[0]:.2f}, {lam[1]:.2f}) | " + " | ".join(cells) + " |")


def plot(results: dict, speeds, family: str, deviation_key: str, survival_key: str, chosen, path: str) -> None:
    fig, (left, right) = figure((8, 3.2), 1, 2)
    for lam, row in results.items():
        left.plot(speeds, [row[s][deviation_key] for s in speeds], "o-", label=f"{lam}")
        right.plot(speeds, [survival(row[s], survival_key) for s in speeds], "o-", label=f"{lam}")
    left.axhline(PAPER_MIDDLE[family]["deviation"], color="k", ls=":", label="paper, (0.5, 0.5)")
    right.axhline(PAPER_MIDDLE[family]["survival"], color="k", ls=":", label="paper, (0.5, 0.5)")
    for ax, name in ((left, deviation_key + " (m)"), (right, "episodes up (%)")):
        if chosen:
            for speed, label in zip(chosen, ("mild", "strong")):
                ax.axvline(speed, color="grey", ls="--")
                ax.text(speed, ax.get_ylim()[1], label, fontsize=7, ha="center", va="bottom")
        ax.set_xlabel("push speed (m/s)")
        ax.set_ylabel(name)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("checkpoint")
    parser.add_argument("--speeds", type=float, nargs="+", help="push speeds, m/s (default: 0.5 to 3.0 by 0.25)")
    parser.add_argument("--num-envs", type=int, default=64, help="episodes per preference and speed")
    parser.add_argument("--preferences", type=int, default=5)
    parser.add_argument("--window", type=float, help="override the preset's window after a push, s")
    parser.add_argument("--calibrate", action="store_true", help="sweep (0.5, 0.5) only and choose the presets")
    parser.add_argument("--plot", metavar="PNG", help="write the sweep as a figure")
    args = parser.parse_args(argv)
    config = task_config_of(args.checkpoint, "g1-", "push_sweep", "a G1 task")
    family, deviation_key, survival_key = task_keys(config["task"])
    speeds = args.speeds or [float(s) for s in np.arange(0.5, 3.01, 0.25)]
    preferences = [(0.5, 0.5)] if args.calibrate else evenly_spaced_preferences(args.preferences)
    results = sweep(args.checkpoint, config, speeds, preferences, args.num_envs, args.window)
    print(f"\nPush sweep of {args.checkpoint} ({config['task']}), {args.num_envs} episodes per cell, mild preset "
          "with the speed changed" + (f", window {args.window:g} s" if args.window else ""))
    print_tables(results, speeds, deviation_key, survival_key)
    chosen = None
    if args.calibrate:
        chosen = choose_presets(results[(0.5, 0.5)], family, deviation_key, survival_key)
        print(f"\ncalibrated presets (rule in tools/diagnostics/push_sweep.py): mild {chosen[0]:g} m/s, "
              f"strong {chosen[1]:g} m/s")
    if args.plot:
        plot(results, speeds, family, deviation_key, survival_key, chosen, args.plot)
        print(f"wrote {args.plot}")
    return {"results": results, "chosen": chosen}


if __name__ == "__main__":
    main()
