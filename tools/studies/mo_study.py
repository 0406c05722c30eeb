"""The MO-Gymnasium study: a grid of tools/studies/mo_benchmark.py runs over seeds, then a table and figures.

    python tools/studies/mo_study.py --out ~/pchc-runs/mo_study            # run what is missing, then report
    python tools/studies/mo_study.py --out ~/pchc-runs/mo_study --report-only --docs docs/results

Resumable: a cell whose folder holds a result.json is skipped, so the study continues where it stopped. Cells run
seed by seed (all of seed 1 first), so a partial study is balanced. Several workers on one machine can share a study
(start the same command once per core): each claims its next cell with a lock file and skips cells another live
worker holds. Three groups of cells:
- main: every task x {pci, pci-blind, gated, mlp}, 1M env steps each (the paper's claim that PCI beats the gate);
- claim (d): on mo-halfcheetah-v5, five fixed-preference policies at lambda_1 = 0, .25, .5, .75, 1, each with a
  fifth of the budget, whose five points form one front, next to the single PCHC policy's;
- routing: the PCI actor's routing scale s and the training preferences' Dirichlet concentration, on the two
  2-objective tasks where the end experts were weak;
- three_objective: on mo-hopper-v5 (this project's Dirichlet extension, six lattice experts), the gate with PCI's
  expert and parameter counts (configs/matched_gate.py), beside the main grid's five-expert gate.
The report (``mo_study.md`` and PNGs) gives each figure as mean and standard deviation over the finished seeds, and
Welch's test of PCI against the gate; blocks of the page between ``<!-- name:start -->`` and ``<!-- name:end -->``
markers (tools/studies/pci_vs_gated.py's section) are kept when it is rewritten.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import subprocess
import sys
import time

import numpy as np

from pchc_rsl.configs import task_config
from pchc_rsl.configs.mo_gym import REFERENCE_POINTS
from pchc_rsl.evaluation.expert_usage import expert_usage
from pchc_rsl.pareto import hypervolume, non_dominated
from pchc_rsl.training.study_cells import Cell, claim_cell

HERE = os.path.dirname(os.path.abspath(__file__))

TASKS = ["mo-hopper-2obj-v5", "mo-halfcheetah-v5", "mo-walker2d-v5", "mo-hopper-v5"]
TWO_OBJECTIVE_TASKS = TASKS[:3]
THREE_OBJECTIVE_TASK = "mo-hopper-v5"
"""The paper's PCI is the two-objective Beta rule; the three-objective task tests this project's Dirichlet extension."""
VARIANTS = ["pci", "pci-blind", "gated", "mlp"]
CLAIM_D_TASK = "mo-halfcheetah-v5"
CLAIM_D_PREFERENCES = [0.0, 0.25, 0.5, 0.75, 1.0]
ROUTING_TASKS = ["mo-hopper-2obj-v5", "mo-halfcheetah-v5"]
STUDY_ROUTING_SCALE = 10.0
"""The study ran with s = 10, the default then; its PCI cells name it so that a rerun reproduces them (the default
is now 3, chosen from the routing rows)."""
ROUTING_SETTINGS = {"pci-s0": (0.0, 1.0), "pci-s3": (3.0, 1.0), "pci-s30": (30.0, 1.0),
                    "pci-c0.5": (STUDY_ROUTING_SCALE, 0.5)}
"""Routing row -> (routing scale s, Dirichlet concentration of the training preferences); row "pci" is the main
grid's (STUDY_ROUTING_SCALE, 1). s = 0 is the even mixture whatever lambda (every expert trains on every sample;
lambda still reaches the experts): the test of whether PCI loses to the gate because its routing splits the data
among the experts."""


def study_cells(seeds: list[int], steps: int) -> list[Cell]:
    cells = []
    for seed in seeds:
        for task in TASKS:
            for variant in VARIANTS:
                scale = ["--routing-scale", f"{STUDY_ROUTING_SCALE:g}"] if variant.startswith("pci") else []
                cells.append(Cell("main", task, variant, seed, ["--variant", variant, "--steps", str(steps), *scale]))
        for lam in CLAIM_D_PREFERENCES:
            cells.append(Cell("claim_d", CLAIM_D_TASK, f"fixed{lam:.2f}", seed,
                              ["--variant", "mlp", "--fixed-preference", f"{lam},{1 - lam}",
                               "--steps", str(steps // len(CLAIM_D_PREFERENCES)), "--eval-every", "0"]))
        for task in ROUTING_TASKS:
            for name, (scale, concentration) in ROUTING_SETTINGS.items():
                cells.append(Cell("routing", task, name, seed, [
                    "--variant", "pci", "--steps", str(steps), "--routing-scale", f"{scale:g}",
                    "--preference-concentration", f"{concentration:g}"]))
        cells.append(Cell("three_objective", THREE_OBJECTIVE_TASK, "gated-matched", seed,
                          ["--variant", "gated", "--match-pci-parameters", "--steps", str(steps)]))
    return cells


def run_cell(cell: Cell, root: str) -> None:
    folder = cell.folder(root)
    if not claim_cell(folder):
        return
    command = [sys.executable, os.path.join(HERE, "mo_benchmark.py"), "--task", cell.task, "--seed", str(cell.seed),
               "--out", folder, *cell.args]
    start = time.time()
    try:
        with open(os.path.join(folder, "log.txt"), "w") as log:
            code = subprocess.call(command, stdout=log, stderr=subprocess.STDOUT)
    finally:
        with contextlib.suppress(FileNotFoundError):  # cleared by another worker that took it for stale
            os.remove(folder + ".claim")
    status = "done" if code == 0 else f"FAILED (exit {code}, see {folder}/log.txt)"
    print(f"[{time.strftime('%H:%M:%S')}] {cell.task} {cell.name} seed {cell.seed}: {status} in "
          f"{time.time() - start:.0f} s", flush=True)


def load_results(cells: list[Cell], root: str) -> dict[tuple[str, str], list[dict]]:
    """(task, name) -> the finished cells' result.json contents, by seed."""
    results: dict[tuple[str, str], list[dict]] = {}
    for cell in cells:
        path = os.path.join(cell.folder(root), "result.json")
        if os.path.isfile(path):
            with open(path) as f:
                results.setdefault((cell.task, cell.name), []).append(json.load(f))
    return results


def expert_training_shares(scale: float, concentration: float, points: int = 20001) -> np.ndarray:
    """[E] mean routing weight of each of the five expert positions over the training preferences (2 objectives).

    lambda_1 ~ Beta(c, c) (the Dirichlet's marginal); the expectation is taken on the distribution's quantile grid,
    so it is exact up to the grid even where the density is unbounded (c < 1). Why it matters: an expert trains on
    the samples in proportion to its weight, so this is each expert's share of the training data.
    """
    import torch
    from scipy.stats import beta

    from pchc_rsl.preference import routing_weights, simplex_lattice

    lam_1 = torch.as_tensor(beta.ppf((np.arange(points) + 0.5) / points, concentration, concentration))
    lam = torch.stack([lam_1, 1 - lam_1], dim=-1)
    positions = simplex_lattice(2, 4).to(lam.dtype)  # PCIActor's five default positions
    return routing_weights(lam, positions, scale=scale).mean(0).numpy()


def routing_usage(root: str, task: str, name: str, seed: int) -> dict | None:
    """pchc_rsl.evaluation.expert_usage's summary of a finished cell's final policy (cached in the cell as
    expert_usage.json): mean over the preferences of the entropy of the mean routing weights and of the entropy state
    by state. None for an unfinished cell."""
    folder = Cell("main", task, name, seed).folder(root)
    cache = os.path.join(folder, "expert_usage.json")
    if not os.path.isfile(cache):
        checkpoint = os.path.join(folder, "train", "model_final.pt")
        if not os.path.isfile(os.path.join(folder, "result.json")) or not os.path.isfile(checkpoint):
            return None
        usage = expert_usage(checkpoint)
        summary = {"entropy": float(usage["entropy"].mean()),
                   "per_state_entropy": float(usage["per_state_entropy"].mean())}
        with open(cache, "w") as f:
            json.dump(summary, f, indent=2)
    with open(cache) as f:
        return json.load(f)


def welch_p(a: list[float], b: list[float]) -> float:
    """Two-sided p of Welch's t-test (unpaired: the main grid's variants share a seed number, not a pairing)."""
    if len(a) < 2 or len(b) < 2:
        return float("nan")
    from scipy import stats

    return float(stats.ttest_ind(a, b, equal_var=False).pvalue)


def carry_marked_sections(old_page: str, new_page: str) -> str:
    """new_page followed by every ``<!-- name:start -->`` ... ``<!-- name:end -->`` block of old_page, so that a
    section another tool writes into the page survives this report."""
    kept = [m.group(0) for m in re.finditer(r"<!-- ([\w-]+):start -->\n.*?<!-- \1:end -->\n", old_page, re.DOTALL)]
    return new_page + "".join("\n" + block for block in kept)


def mean_std(values: list[float]) -> str:
    if not values:
        return "-"
    if len(values) == 1:
        return f"{values[0]:.4g}"
    return f"{np.mean(values):.4g} ± {np.std(values, ddof=1):.2g}"


def claim_d_fronts(results: dict, seeds: list[int]) -> dict[int, float]:
    """seed -> hypervolume of the front formed by that seed's five fixed-preference policies (all five finished)."""
    hv = {}
    for seed in seeds:
        points = []
        for lam in CLAIM_D_PREFERENCES:
            runs = [r for r in results.get((CLAIM_D_TASK, f"fixed{lam:.2f}"), []) if r["seed"] == seed]
            if runs:
                points.append(runs[0]["rows"][0]["mean_return"])
        if len(points) == len(CLAIM_D_PREFERENCES):
            hv[seed] = hypervolume(non_dominated(points), REFERENCE_POINTS[CLAIM_D_TASK])
    return hv


def markdown_report(results: dict, seeds: list[int], steps: int, total_cells: int, root: str) -> str:
    finished = sum(len(runs) for runs in results.values())
    lines = [
        "# MO-Gymnasium study",
        "",
        f"**{finished} of {total_cells} cells finished**" + ("" if finished == total_cells else
                                                               " (the others are not run yet; n per row below)."),
        "",
        f"Reproduce: `python tools/studies/mo_study.py --out RUNS --seeds {' '.join(map(str, seeds))} --steps {steps}` "
        "(resumable), then `--report-only --docs docs/results`.",
        f"Each run: {steps} env steps (16 envs x 128 steps per iteration), evaluated with the deterministic policy "
        "on the raw env at 11 evenly spaced preferences (2 objectives) or the 28 points of the resolution-6 simplex "
        "lattice (3 objectives), 5 seeded episodes each, undiscounted returns. HV: hypervolume of the "
        "non-dominated points (reference point per task below); S: sparsity (lower is denser). Mean ± standard "
        "deviation over seeds "
        "(n = number of finished seeds).",
        "",
        "## PCI against the ablations",
        "",
        "pci: the PCI actor (experts see lambda), pci-blind: its experts blind to lambda, both at routing scale "
        "s = 10; gated: the same experts under a learned softmax gate (the paper's \"w/o PCI\"); mlp: one MLP on "
        "[observation, lambda].",
        "",
        "| task | reference point | variant | HV | S | non-dominated points | n |",
        "|---|---|---|---|---|---|---|",
    ]
    for task in TWO_OBJECTIVE_TASKS:
        for variant in VARIANTS:
            runs = results.get((task, variant), [])
            lines.append(
                f"| {task} | {REFERENCE_POINTS[task]} | {variant} | {mean_std([r['hypervolume'] for r in runs])} | "
                f"{mean_std([r['sparsity'] for r in runs])} | {mean_std([r['num_points'] for r in runs])} | "
                f"{len(runs)} |"
            )
    lines += ["", "Mean HV of PCI over mean HV of each other variant (above 1: PCI's front is larger), and Welch's test "
              "of PCI's HV against the gate's:", "",
              "| task | pci / pci-blind | pci / gated | pci / mlp | p, pci vs gated (Welch) |", "|---|---|---|---|---|"]
    for task in TWO_OBJECTIVE_TASKS:
        hv = {v: [r["hypervolume"] for r in results.get((task, v), [])] for v in VARIANTS}
        means = {v: np.mean(hv[v] or [np.nan]) for v in VARIANTS}
        lines.append(f"| {task} | " + " | ".join(f"{means['pci'] / means[v]:.2f}" for v in VARIANTS[1:])
                     + f" | {welch_p(hv['pci'], hv['gated']):.2f} |")
    lines += ["", "With three seeds per variant these ratios are not resolved: none of the three tasks separates PCI "
              "from the gate at the 5% level, and on mo-halfcheetah-v5 the seeds' spread cannot tell a front 20% "
              "smaller from one 40% larger. The paired, longer study below (section \"Does PCI help?\") answers it for "
              "mo-halfcheetah-v5 at 2M env steps, and for no other task or budget. The three-objective task has its "
              "own section."]
    lines += three_objective_section(results)
    hv_d = claim_d_fronts(results, seeds)
    pci = {r["seed"]: r["hypervolume"] for r in results.get((CLAIM_D_TASK, "pci"), [])}
    lines += [
        "",
        "## Claim (d): one policy against one policy per preference (equal total env steps)",
        "",
        f"{CLAIM_D_TASK}: five fixed-preference policies (plain MLP, lambda_1 = "
        f"{', '.join(map(str, CLAIM_D_PREFERENCES))}, {steps // len(CLAIM_D_PREFERENCES)} steps each), each "
        "evaluated at its own preference; their five points form one front.",
        "",
        "| seed | HV, five fixed-preference policies | HV, one PCHC (pci) policy |",
        "|---|---|---|",
    ]
    for seed in seeds:
        if seed in hv_d or seed in pci:
            fixed = f"{hv_d[seed]:.4g}" if seed in hv_d else "-"
            single = f"{pci[seed]:.4g}" if seed in pci else "-"
            lines.append(f"| {seed} | {fixed} | {single} |")
    lines.append(f"| mean | {mean_std(list(hv_d.values()))} | {mean_std(list(pci.values()))} |")
    lines += [
        "",
        "## Routing scale and preference concentration (PCI)",
        "",
        "The study's PCI rows use routing scale s = 10 and Dirichlet concentration 1 (row pci), the defaults when "
        "it ran; from these rows the default routing scale is now s = 3 (row pci-s3). The end-point columns are the "
        "returns at lambda = (1, 0) and (0, 1), where the end experts act. End-expert share: the mean routing weight "
        "of each end expert (x = 0 and x = 1) over the training preferences, i.e. its share of the training data "
        "(0.2 would be an equal share of five; computed, not measured).",
        "",
        "| task | setting | HV | return at (1, 0) | return at (0, 1) | end-expert share | n |",
        "|---|---|---|---|---|---|---|",
    ]
    for task in ROUTING_TASKS:
        for name in ["pci", *ROUTING_SETTINGS]:
            runs = results.get((task, name), [])
            first = [r["rows"][0]["mean_return"][0] for r in runs]
            last = [r["rows"][-1]["mean_return"][1] for r in runs]
            share = expert_training_shares(*{"pci": (STUDY_ROUTING_SCALE, 1.0), **ROUTING_SETTINGS}[name])[-1]
            lines.append(f"| {task} | {name} | {mean_std([r['hypervolume'] for r in runs])} | {mean_std(first)} | "
                         f"{mean_std(last)} | {share:.3f} | {len(runs)} |")
    lines += ["", "## What the learned gate does", "",
              "`tools/diagnostics/expert_usage.py` on each seed's final policy: routing weights over 8 envs x 200 "
              "steps of its "
              "own rollout at each of 11 preferences. Entropy (nats; 1.609 = even over 5 experts) of the mean weights "
              "at a preference, and state by state, averaged over the preferences; experts per action: exp(entropy "
              "per state), the effective number of experts each action is drawn from (5 = even).", "",
              "| task | actor | entropy of mean weights | entropy per state | experts per action | n |",
              "|---|---|---|---|---|---|"]
    for task in ROUTING_TASKS + ["mo-walker2d-v5"]:
        for name in ["pci", "gated"]:
            usage = [u for u in (routing_usage(root, task, name, seed) for seed in seeds) if u is not None]
            lines.append(f"| {task} | {name} | {mean_std([u['entropy'] for u in usage])} | "
                         f"{mean_std([u['per_state_entropy'] for u in usage])} | "
                         f"{mean_std([float(np.exp(u['per_state_entropy'])) for u in usage])} | {len(usage)} |")
    lines += ["", "Figures: `mo_study_fronts.png` (every seed's front, per task and variant), "
              "`mo_study_hv.png` (hypervolume against env steps, mean over seeds), `mo_study_claim_d.png` (claim (d))."]
    return "\n".join(lines) + "\n"


def three_objective_section(results: dict) -> list[str]:
    """mo-hopper-v5 on its own: it tests the Dirichlet extension (six lattice experts), not the paper's Beta PCI."""
    task = THREE_OBJECTIVE_TASK
    lines = ["", f"## Three objectives: {task} (this project's extension)", "",
             "The paper's PCI routes two objectives with a Beta density; for three, this project routes six experts on "
             "the resolution-2 simplex lattice with a Dirichlet density. The main grid's gate has the GatedMoEActor "
             "default of five experts (27,863 parameters against PCI's 31,893); gated-matched has PCI's six experts "
             "and its parameter count (31,503; configs/matched_gate.py), the fair comparison.", "",
             f"| variant | HV (reference point {REFERENCE_POINTS[task]}) | S | non-dominated points | n |",
             "|---|---|---|---|---|"]
    for variant in [*VARIANTS, "gated-matched"]:
        runs = results.get((task, variant), [])
        lines.append(f"| {variant} | {mean_std([r['hypervolume'] for r in runs])} | "
                     f"{mean_std([r['sparsity'] for r in runs])} | {mean_std([r['num_points'] for r in runs])} | "
                     f"{len(runs)} |")
    hv = {v: [r["hypervolume"] for r in results.get((task, v), [])] for v in [*VARIANTS, "gated-matched"]}
    mean = {v: np.mean(values) if values else float("nan") for v, values in hv.items()}
    lines += ["", f"PCI over the five-expert gate: {mean['pci'] / mean['gated']:.2f} (Welch p = "
              f"{welch_p(hv['pci'], hv['gated']):.3f}); over the matched six-expert gate: "
              + (f"{mean['pci'] / mean['gated-matched']:.2f} (Welch p = {welch_p(hv['pci'], hv['gated-matched']):.3f})"
                 if hv["gated-matched"] else "not run yet (`--groups three_objective`)") + "."]
    return lines


def plot_fronts(results: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(TASKS), figsize=(4.2 * len(TASKS), 3.8))
    for ax, task in zip(axes, TASKS):
        for i, variant in enumerate(VARIANTS):
            for j, run in enumerate(results.get((task, variant), [])):
                front = np.array(run["front"])
                order = np.argsort(front[:, 0])
                ax.plot(front[order, 0], front[order, 1], "o-", ms=3, lw=0.8, color=f"C{i}", alpha=0.8,
                        label=variant if j == 0 else None)
        names = task_config(task).env.objective_names
        ax.set_title(task + (" (first 2 objectives)" if len(names) > 2 else ""), fontsize=9)
        ax.set_xlabel(names[0])
        ax.set_ylabel(names[1])
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def plot_hypervolume(results: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(TASKS), figsize=(4.2 * len(TASKS), 3.5))
    for ax, task in zip(axes, TASKS):
        for i, variant in enumerate(VARIANTS):
            runs = results.get((task, variant), [])
            if not runs:
                continue
            steps = [h["env_steps"] for h in runs[0]["history"]]
            curves = np.array([[h["hypervolume"] for h in r["history"]] for r in runs
                               if len(r["history"]) == len(steps)])
            mean, std = curves.mean(0), curves.std(0)
            ax.plot(steps, mean, "o-", color=f"C{i}", label=f"{variant} (n={len(curves)})")
            ax.fill_between(steps, mean - std, mean + std, color=f"C{i}", alpha=0.15)
        ax.set_title(task, fontsize=9)
        ax.set_xlabel("env steps")
        ax.set_ylabel("hypervolume")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def plot_claim_d(results: dict, seeds: list[int], path: str) -> None:
    """Claim (d): each seed's five fixed-preference points (and their front) next to the single PCHC policy's."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    for k, seed in enumerate(seeds):
        fixed = [r["rows"][0]["mean_return"] for lam in CLAIM_D_PREFERENCES
                 for r in results.get((CLAIM_D_TASK, f"fixed{lam:.2f}"), []) if r["seed"] == seed]
        if fixed:
            points = np.array(fixed)
            ax.plot(points[:, 0], points[:, 1], "s", color="C1", alpha=0.8,
                    label="five fixed-preference policies" if k == 0 else None)
        for r in results.get((CLAIM_D_TASK, "pci"), []):
            if r["seed"] == seed:
                front = np.array(r["front"])
                order = np.argsort(front[:, 0])
                ax.plot(front[order, 0], front[order, 1], "o-", color="C0", ms=3, alpha=0.8,
                        label="one PCHC policy (front)" if k == 0 else None)
    ax.set_xlabel("forward")
    ax.set_ylabel("energy")
    ax.set_title(f"{CLAIM_D_TASK}: equal total env steps", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True, help="folder of the runs (keep it outside the repository)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--steps", type=int, default=1_000_000)
    parser.add_argument("--groups", nargs="+", default=["main", "claim_d", "routing", "three_objective"],
                        choices=["main", "claim_d", "routing", "three_objective"])
    parser.add_argument("--report-only", action="store_true", help="write the report from finished cells only")
    parser.add_argument("--docs", help="also copy the report and figures into this folder (e.g. docs/results)")
    args = parser.parse_args(argv)

    cells = [c for c in study_cells(args.seeds, args.steps) if c.group in args.groups]
    if not args.report_only:
        todo = [c for c in cells if not os.path.isfile(os.path.join(c.folder(args.out), "result.json"))]
        print(f"{len(cells) - len(todo)} of {len(cells)} cells finished; running {len(todo)}", flush=True)
        for cell in todo:
            run_cell(cell, args.out)
    results = load_results(cells, args.out)
    for folder in [args.out] + ([args.docs] if args.docs else []):
        os.makedirs(folder, exist_ok=True)
        page_path = os.path.join(folder, "mo_study.md")
        old_page = open(page_path).read() if os.path.isfile(page_path) else ""
        with open(page_path, "w") as f:
            f.write(carry_marked_sections(old_page, markdown_report(results, args.seeds, args.steps, len(cells),
                                                                    args.out)))
        plot_fronts(results, os.path.join(folder, "mo_study_fronts.png"))
        plot_hypervolume(results, os.path.join(folder, "mo_study_hv.png"))
        plot_claim_d(results, args.seeds, os.path.join(folder, "mo_study_claim_d.png"))
    print(f"report: {os.path.join(args.out, 'mo_study.md')}" + (f" and {args.docs}" if args.docs else ""))


if __name__ == "__main__":
    main()
