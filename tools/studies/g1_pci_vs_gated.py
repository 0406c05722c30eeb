"""PCI against the matched learned gate on a G1 task, paired by seed: does the G1's shared history encoder keep
PCI's lambda-routed experts from losing the data they need?

    python tools/studies/g1_pci_vs_gated.py --pci RUN_S1 RUN_S2 ... --gate RUN_S1 RUN_S2 ... --iteration 149 \
        --pushes mild --json docs/results/data/g1_pci_vs_gated/pushes-mild.json

On MO-Gym tasks PCI's experts are disjoint networks, and its routing sends each end of the simplex to its own
experts: there it loses to the gate (docs/results/mo_study.md). On the G1 every expert reads a shared history
encoder. Runs are pchc-train runs of the same task, seed for seed, one with ``--actor pci`` and one with ``--actor
gated`` and the expert widths that match PCI's parameter count (configs/matched_gate.py). Each run's checkpoint at
``--iteration`` is evaluated at evenly spaced preferences (the task's evaluation preset, pushes off unless
``--pushes`` names a preset, ``--num-envs`` first episodes each): the task group's return, each objective's return,
falls and episode length.

Four measures per run: the task return averaged over the preferences (how far training has got), the ends' share,
the mean task return at the two ends over the one at the middle preference (where routing by lambda splits the data,
the ends learn from fewer samples and lag the middle), the training reward (rsl-rl's Train/mean_reward over the
run's last 10 iterations: sampled actions, sampled preferences, the training pushes), and the hypervolume of the
objective returns over the preferences (whether the policy trades the objectives along lambda; its reference point,
unless given, is each objective's worst return over every run of the study less a tenth of its spread). Each gets
the study's paired log ratio gate / PCI with a 95% Student-t interval over the seeds
(pchc_rsl.evaluation.statistics.paired_log_ratio).
"""

from __future__ import annotations

import argparse
import os

import numpy as np

from pchc_rsl.evaluation import evenly_spaced_preferences
from pchc_rsl.evaluation.group_returns import first_episode_returns, policy_under_pushes
from pchc_rsl.evaluation.statistics import paired_log_ratio
from pchc_rsl.evaluation.training_plots import read_scalars
from pchc_rsl.pareto import hypervolume
from pchc_rsl.training.run_folder import checkpoints_in
from pchc_rsl.utils.files import write_json

NOT_OBJECTIVES = ("preference", "task", "falls", "episode_s")


def checkpoint_of(run: str, iteration: int) -> str:
    path = os.path.join(run, f"model_{iteration}.pt")
    if not os.path.isfile(path):
        saved = ", ".join(os.path.basename(p) for p in checkpoints_in(run)) or "none"
        raise SystemExit(f"g1_pci_vs_gated: {path} does not exist (saved: {saved})")
    return path


def evaluate_run(checkpoint: str, preferences: int, num_envs: int, pushes: str) -> dict:
    """Per preference: mean task and objective returns, fall share and episode length in seconds; and the run's
    training reward."""
    cfg, runner, policy = policy_under_pushes(checkpoint, pushes, num_envs, "g1_pci_vs_gated")
    env = runner.env
    names = ["task", *cfg.env.objective_names]
    rows = []
    for lam in evenly_spaced_preferences(preferences):
        returns, fell, lengths = first_episode_returns(env, policy, lam)
        row = {"preference": list(lam), "falls": float(fell.float().mean()),
               "episode_s": float(lengths.float().mean()) * env.dt}
        row |= {name: float(returns[:, i].mean()) for i, name in enumerate(names)}
        rows.append(row)
        print(f"  {checkpoint} ({lam[0]:.2f}, {lam[1]:.2f}): " + ", ".join(
            f"{k} {v:.3f}" for k, v in row.items() if k != "preference"), flush=True)
    _, rewards = read_scalars(os.path.dirname(checkpoint), "Train/mean_reward")
    return {"checkpoint": checkpoint, "per_preference": rows, "training_reward": float(rewards[-10:].mean())}


def objective_names(result: dict) -> list[str]:
    """The run's objectives, in its rows' order: every reward group but the task."""
    return [k for k in result["per_preference"][0] if k not in NOT_OBJECTIVES]


def objective_points(result: dict) -> np.ndarray:
    """[preferences, objectives] the run's objective returns."""
    names = objective_names(result)
    return np.array([[row[n] for n in names] for row in result["per_preference"]])


def reference_point(results: list[dict]) -> list[float]:
    """Each objective's worst return over the runs, less a tenth of its spread (so that no run's worst point is
    lost on the boundary)."""
    points = np.concatenate([objective_points(r) for r in results])
    low, high = points.min(axis=0), points.max(axis=0)
    return (low - 0.1 * np.maximum(high - low, 1e-9)).tolist()


def run_measures(result: dict, reference: list[float]) -> dict:
    """The task return averaged over the preferences, the ends' share (ends' mean over the middle's), the training
    reward and the hypervolume of the objective returns."""
    task = np.array([row["task"] for row in result["per_preference"]])
    middle = task[len(task) // 2]
    return {"mean_task_return": float(task.mean()), "ends_share": float((task[0] + task[-1]) / 2 / middle),
            "training_reward": result["training_reward"],
            "hypervolume": hypervolume(objective_points(result), reference)}


def compare(pci: list[dict], gate: list[dict]) -> dict:
    """Paired log ratios gate / PCI of each measure (run_measures of each run; positive measures only, otherwise
    the mean difference)."""
    out = {}
    for measure in pci[0]:
        a = [m[measure] for m in gate]
        b = [m[measure] for m in pci]
        if min(a + b) > 0:
            out[measure] = paired_log_ratio(a, b)
        else:
            out[measure] = {"n": len(a), "mean_difference": float(np.mean(np.subtract(a, b))), "values_gate": a,
                            "values_pci": b}
    return out


def markdown(results: dict, measures: dict, comparison: dict, reference: list[float]) -> str:
    """The runs' rows, each run's measures and the paired ratios, as printed."""
    pci, gate = results["pci"], results["gate"]
    names = objective_names(pci[0])
    lines = ["| run | preference | task return | " + " | ".join(names) + " | falls | episode (s) |",
             "|---" * (5 + len(names)) + "|"]
    for label, runs in (("PCI", pci), ("gate", gate)):
        for result in runs:
            for row in result["per_preference"]:
                objectives = [f"{row[k]:.3f}" for k in names]
                lines.append(f"| {label} {result['checkpoint']} | ({row['preference'][0]:.2f}, "
                             f"{row['preference'][1]:.2f}) | {row['task']:.2f} | " + " | ".join(objectives)
                             + f" | {100 * row['falls']:.0f}% | {row['episode_s']:.2f} |")
    lines.append("")
    for label, name in (("PCI", "pci"), ("gate", "gate")):
        for result, measured in zip(results[name], measures[name]):
            lines.append(f"- {label} {result['checkpoint']}: " + ", ".join(f"{k} {v:.4g}" for k, v in measured.items()))
    lines.append("- hypervolume's reference point: (" + ", ".join(f"{v:.3f}" for v in reference) + ")")
    for measure, stats in comparison.items():
        if "ratio" in stats:
            lines.append(f"- {measure}: gate / PCI {stats['ratio']:.3f} [{stats['ratio_ci95'][0]:.3f}, "
                         f"{stats['ratio_ci95'][1]:.3f}] (n = {stats['n']}; pairs' ratios "
                         + ", ".join(f"{np.exp(d):.3f}" for d in stats["log_ratios"]) + ")")
        else:
            lines.append(f"- {measure}: gate - PCI {stats['mean_difference']:.3f} (n = {stats['n']})")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--pci", nargs="+", required=True, help="PCI run folders, in seed order")
    parser.add_argument("--gate", nargs="+", required=True, help="the gated runs of the same seeds, in the same order")
    parser.add_argument("--iteration", type=int, required=True, help="the checkpoint of every run (model_<it>.pt)")
    parser.add_argument("--preferences", type=int, default=5)
    parser.add_argument("--num-envs", type=int, default=32, help="first episodes per preference")
    parser.add_argument("--pushes", default="off", help="off (default), or one of the task's push presets")
    parser.add_argument("--reference-point", type=lambda t: [float(v) for v in t.split(",")], metavar="R1,R2",
                        help="the hypervolume's reference point (default: from the runs' worst returns)")
    parser.add_argument("--json", help="write the runs' rows and the intervals here")
    args = parser.parse_args(argv)
    if len(args.pci) != len(args.gate):
        parser.error(f"--pci has {len(args.pci)} runs and --gate {len(args.gate)}: they pair seed by seed")
    paths = {name: [checkpoint_of(run, args.iteration) for run in getattr(args, name)] for name in ("pci", "gate")}
    results = {name: [evaluate_run(p, args.preferences, args.num_envs, args.pushes) for p in ckpts]
               for name, ckpts in paths.items()}
    reference = args.reference_point or reference_point(results["pci"] + results["gate"])
    measures = {name: [run_measures(r, reference) for r in runs] for name, runs in results.items()}
    comparison = compare(measures["pci"], measures["gate"])
    print(markdown(results, measures, comparison, reference))
    report = {"settings": vars(args), **results, "reference_point": reference, "measures": measures,
              "gate_over_pci": comparison}
    if args.json:
        write_json(args.json, report)
    return report


if __name__ == "__main__":
    main()
