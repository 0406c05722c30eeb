"""Does PCI help? The PCI actor against the learned gate on mo-halfcheetah-v5, paired by seed.

    python tools/studies/pci_vs_gated.py --out ~/pchc-runs/pci-study  # run what is missing (resumable), then report
    python tools/studies/pci_vs_gated.py --out ~/pchc-runs/pci-study --report-only --docs docs/results

Each seed trains PCI at routing scale 3 and the gated mixture sized like it (as many experts, parameter count within
0.3%: configs/matched_gate.py), 2M env steps each, evaluated every 250k env steps (tools/studies/mo_benchmark.py). Two
measures: the hypervolume and the expected utility (lambda . range-normalised returns, averaged over the evaluation
preferences). A single evaluation is noisy, so each run's figure is the mean of its evaluations at 1.5M, 1.75M and 2M
steps; the seeds pair the two variants (same seed, same evaluation episodes), and the mean log-ratio log(PCI / gated)
over the pairs gets a 95% Student-t interval. The 1M evaluation of the same runs is reported beside it.

Cells run seed by seed, PCI then gated, so a partial study is paired. They are claimed as mo_study.py's are
(pchc_rsl/training/study_cells.py): a finished cell (its result.json, written atomically at its end) is skipped, an
interrupted one resumes from its newest checkpoint (tools/studies/mo_benchmark.py --resume), and several workers may
share the study. The report writes ``pci_vs_gated.json`` (one row per run with its evaluations, then the intervals),
``pci_vs_gated.png``, and the study's section of ``mo_study.md``.

A run folder lives on one machine; the report in the repository outlives it. Runs recorded as finished in
``--landed`` (default: the repository's docs/results/pci_vs_gated.json) count as finished: they are not trained
again and their rows stay in the report, so the study continues on any machine from what has landed.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys

from pchc_rsl.configs.mo_gym import OBJECTIVE_RANGES, REFERENCE_POINTS
from pchc_rsl.evaluation.statistics import paired_log_ratio, pairs_for_power  # noqa: F401 - the study's statistics
from pchc_rsl.training import study_cells
from pchc_rsl.training.study_cells import Cell, run_checkpoints, run_figure, run_row
from pchc_rsl.utils.files import write_json

HERE = os.path.dirname(os.path.abspath(__file__))

TASK = "mo-halfcheetah-v5"
ROUTING_SCALE = 3.0
STEPS = 2_000_000
EVAL_EVERY = 250_000
FINAL_WINDOW = (1_500_000, 1_750_000, 2_000_000)
"""Grid points averaged into a run's figure."""
MIDPOINT = 1_000_000
SEEDS = list(range(8))
VARIANT_ARGS = {
    "pci": ["--variant", "pci", "--routing-scale", f"{ROUTING_SCALE:g}"],
    "gated": ["--variant", "gated", "--match-pci-parameters"],
}
MEASURES = ("hypervolume", "expected_utility")
SECTION = "pci-vs-gated"
LANDED = os.path.join(HERE, "..", "..", "docs", "results", "pci_vs_gated.json")


def study_cells(seeds: list[int]) -> list[Cell]:
    """Seed by seed, PCI then gated."""
    return [Cell("pci_vs_gated", TASK, variant, seed,
                 [*args, "--steps", str(STEPS), "--eval-every", str(EVAL_EVERY)])
            for seed in seeds for variant, args in VARIANT_ARGS.items()]


def cell_command(cell: Cell, root: str) -> list[str]:
    return [sys.executable, os.path.join(HERE, "mo_benchmark.py"), "--task", cell.task, "--seed", str(cell.seed),
            "--out", cell.folder(root), *cell.args]


def run_cell(cell: Cell, root: str) -> None:
    """Train and evaluate one cell unless it is finished or claimed; an interrupted cell resumes."""
    study_cells.run_cell(cell, root, [*cell_command(cell, root), "--resume"])













def analysis(rows: list[dict]) -> dict:
    """For each measure, at the final window and at 1M: the paired log-ratio PCI / gated over the complete pairs."""
    out = {}
    for label, grid in (("final", FINAL_WINDOW), ("1M", (MIDPOINT,))):
        for measure in MEASURES:
            pairs = []
            for seed in sorted({r["seed"] for r in rows}):
                figures = {r["variant"]: run_figure(r, measure, grid) for r in rows if r["seed"] == seed}
                if figures.get("pci") is not None and figures.get("gated") is not None:
                    pairs.append((seed, figures["pci"], figures["gated"]))
            result = paired_log_ratio([p[1] for p in pairs], [p[2] for p in pairs])
            result["seeds"] = [p[0] for p in pairs]
            out[f"{label}/{measure}"] = result
    return out


def landed_rows(path: str | None) -> list[dict]:
    """The finished runs of an earlier report (its JSON's ``runs``); none where there is no such file."""
    if not path or not os.path.isfile(path):
        return []
    with open(path) as f:
        study = json.load(f)
    if study.get("task") != TASK or study.get("steps") != STEPS:
        raise SystemExit(f"{path} is a report of {study.get('task')} at {study.get('steps')} env steps, not of "
                         f"{TASK} at {STEPS}: pass --landed with this study's report, or --landed ''")
    return study["runs"]


def load_rows(root: str, seeds: list[int], landed: list[dict] | None = None) -> list[dict]:
    """One row per finished cell, in the study's order: from its result.json in the run folder, else from the
    landed report."""
    by_cell = {(r["variant"], r["seed"]): r for r in landed or []}
    rows = []
    for cell in study_cells(seeds):
        path = os.path.join(cell.folder(root), "result.json")
        if os.path.isfile(path):
            with open(path) as f:
                result = json.load(f)
            rows.append(run_row(result))
        elif (cell.name, cell.seed) in by_cell:
            rows.append(by_cell[(cell.name, cell.seed)])
    return rows


def unfinished_runs(root: str, seeds: list[int], landed: list[dict] | None = None) -> list[dict]:
    """Started cells without a result: how far their newest checkpoint got (where a resumed run continues)."""
    finished = {(r["variant"], r["seed"]) for r in landed or []}
    runs = []
    for cell in study_cells(seeds):
        folder = cell.folder(root)
        if (cell.name, cell.seed) in finished:
            continue
        if os.path.isdir(folder) and not os.path.isfile(os.path.join(folder, "result.json")):
            saved = run_checkpoints(folder)
            steps = (max(saved) + 1) * 2048 if saved else 0  # 16 envs x 128 steps per update
            runs.append({"variant": cell.name, "seed": cell.seed, "env_steps_checkpointed": steps})
    return runs


def commands(seeds: list[int]) -> dict:
    """The command that reproduces each cell, and the one that runs (or continues) the whole study."""
    cells = {f"{c.name}/seed{c.seed}": " ".join(["python tools/studies/mo_benchmark.py", "--task", c.task, "--seed",
                                                 str(c.seed), "--out", f"RUNS/{c.task}/{c.name}_seed{c.seed}",
                                                 *c.args]) for c in study_cells(seeds)}
    return {"study": "python tools/studies/pci_vs_gated.py --out RUNS",
            "report": "python tools/studies/pci_vs_gated.py --out RUNS --report-only --docs docs/results",
            "cells": cells}


def study_json(rows: list[dict], seeds: list[int], unfinished: list[dict] | None = None) -> dict:
    cpu = [r["cpu_seconds"] for r in rows if r["cpu_seconds"] is not None]
    return {
        "task": TASK, "steps": STEPS, "eval_every": EVAL_EVERY, "final_window": list(FINAL_WINDOW),
        "reference_point": list(REFERENCE_POINTS[TASK]),
        "objective_range": {"low": list(OBJECTIVE_RANGES[TASK][0]), "high": list(OBJECTIVE_RANGES[TASK][1])},
        "variants": {"pci": f"PCI actor, routing scale {ROUTING_SCALE:g}",
                     "gated": "learned-gate mixture, PCI's expert count, parameter count matched"},
        "planned_seeds": seeds, "finished_runs": len(rows), "core_hours": sum(cpu) / 3600,
        "core_hours_complete": all(r["cpu_seconds_complete"] for r in rows),
        "runs": rows, "unfinished_runs": unfinished or [],
        "paired_log_ratio_pci_over_gated": analysis(rows), "commands": commands(seeds),
    }


def interval_text(a: dict) -> str:
    if a["n"] < 2:
        return f"n = {a['n']}: no interval"
    low, high = a["ratio_ci95"]
    return (f"{a['mean_log_ratio']:+.3f} [{a['ci95'][0]:+.3f}, {a['ci95'][1]:+.3f}]; ratio {a['ratio']:.2f} "
            f"[{low:.2f}, {high:.2f}], n = {a['n']}")


def verdict(a: dict, measure: str) -> str:
    """What the interval allows, in words."""
    if a["n"] < 2:
        return f"{measure}: too few pairs for an interval"
    low, high = a["ratio_ci95"]
    if low > 1:
        return f"{measure}: PCI larger (the whole interval lies above 1)"
    if high < 1:
        return f"{measure}: PCI smaller (the whole interval lies below 1)"
    needed = a.get("pairs_for_80pct_power")
    size = (f"; with the measured mean and spread as the truth, {needed} pairs would show it 80% of the time"
            if needed else "; the measured difference is too small against its spread for any study size here")
    return f"{measure}: no difference shown; the interval allows PCI/gated from {low:.2f} to {high:.2f}{size}"


def markdown_section(study: dict) -> str:
    a = study["paired_log_ratio_pci_over_gated"]
    pairs = a["final/hypervolume"]["n"]
    planned = len(study["planned_seeds"])
    lo, hi = study["objective_range"]["low"], study["objective_range"]["high"]
    lines = [
        "## Does PCI help? PCI against the learned gate, paired by seed",
        "",
        f"{TASK} (its front trades forward speed against energy), {study['steps']:,} env steps per run, evaluated "
        f"every {study['eval_every']:,} env steps. pci: the PCI actor at routing scale {ROUTING_SCALE:g}; gated: the "
        "same experts under a learned gate, with PCI's expert count and parameter count (configs/matched_gate.py: "
        "29,156 against 29,231 parameters, the gate's experts [62, 62] wide). Each run's figure is the mean of its "
        "evaluations at 1.5M, 1.75M and 2M env steps; PCI and gated runs with the same seed form a pair (same "
        "training seed, same evaluation episodes). Measures: the hypervolume (reference point "
        f"{tuple(study['reference_point'])}) and the expected utility, the mean over the 11 evaluation preferences of "
        f"lambda . returns normalised per objective to [0, 1] by the ranges forward [{lo[0]:g}, {hi[0]:g}], energy "
        f"[{lo[1]:g}, {hi[1]:g}]. Interval: 95% Student t of the mean paired log-ratio log(PCI / gated), and its "
        "exp as a ratio (above 1: PCI larger).",
        "",
        f"**{study['finished_runs']} of {2 * planned} runs finished, {pairs} of {planned} pairs.**"
        + ("" if pairs == planned else " No interval yet: an interval needs two pairs." if pairs < 2 else
           f" The intervals below are provisional: {pairs} of the {planned} planned pairs, so they are wider than "
           "the finished study's will be."),
        "",
        *([f"Started and not finished (they resume from their checkpoints): "
           + ", ".join(f"{u['variant']} seed {u['seed']} ({u['env_steps_checkpointed']:,} env steps checkpointed)"
                       for u in study["unfinished_runs"]) + ".", ""] if study["unfinished_runs"] else []),
        "| measure | at | paired log-ratio PCI / gated [95% CI]; ratio [95% CI] | what it allows |",
        "|---|---|---|---|",
    ]
    for label, at in (("final", "mean of 1.5M, 1.75M, 2M"), ("1M", "1M")):
        for measure in MEASURES:
            entry = a[f"{label}/{measure}"]
            lines.append(f"| {measure.replace('_', ' ')} | {at} | {interval_text(entry)} | "
                         f"{verdict(entry, measure.replace('_', ' '))} |")
    lines += ["", "| variant | seed | env steps | HV (final mean) | EU (final mean) | HV at 1M | EU at 1M | "
              "routing mass per expert, last tenth of training | core-hours |", "|---|---|---|---|---|---|---|---|---|"]
    for row in study["runs"]:
        figures = [run_figure(row, m, g) for g in (FINAL_WINDOW, (MIDPOINT,)) for m in MEASURES]
        shown = [f"{v:.4g}" if v is not None else "-" for v in figures]
        mass = ", ".join(f"{v:.2f}" for v in row["routing_mass_last_tenth"]) if row["routing_mass_last_tenth"] else "-"
        cpu = "-" if row["cpu_seconds"] is None else (("" if row["cpu_seconds_complete"] else "at least ")
                                                       + f"{row['cpu_seconds'] / 3600:.2f}")
        lines.append(f"| {row['variant']} | {row['seed']} | {row['env_steps']:,} | " + " | ".join(shown)
                     + f" | {mass} | {cpu} |")
    lines += [
        "",
        f"![PCI against the matched gate on {TASK}](pci_vs_gated.png)",
        "",
        f"Core-hours spent on the finished runs: {'' if study['core_hours_complete'] else 'at least '}"
        f"{study['core_hours']:.2f} (CPU time; a run resumed from a session that was not timed counts only its "
        "timed sessions). Data: `pci_vs_gated.json` (every "
        "evaluation of every run, the intervals, the commands); figure: `pci_vs_gated.png` (each run's measures "
        "against env steps, and each pair's log-ratio with the interval).",
        "",
        "Reproduce or continue the whole study (resumable; RUNS is the run folder, and the finished runs recorded in "
        f"`pci_vs_gated.json` are kept, not trained again): `{study['commands']['study']}`, "
        f"then `{study['commands']['report']}`. One cell, e.g. pci seed 0: "
        f"`{study['commands']['cells']['pci/seed0']}`; gated seed 0: `{study['commands']['cells']['gated/seed0']}` "
        "(other seeds: change `--seed` and the folder; every cell's command is in the JSON). All at one thread "
        "(`OMP_NUM_THREADS=1`).",
    ]
    return "\n".join(lines) + "\n"


def replace_section(page: str, name: str, body: str) -> str:
    """The page with the block between ``<!-- name:start -->`` and ``<!-- name:end -->`` replaced (appended if absent)."""
    block = f"<!-- {name}:start -->\n{body}<!-- {name}:end -->\n"
    pattern = re.compile(rf"<!-- {re.escape(name)}:start -->\n.*?<!-- {re.escape(name)}:end -->\n", re.DOTALL)
    if pattern.search(page):
        return pattern.sub(lambda _: block, page)
    return page.rstrip("\n") + "\n\n" + block


def plot(study: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(14, 3.8))
    colours = {"pci": "C0", "gated": "C1"}
    for ax, measure in zip(axes[:2], MEASURES):
        for variant, colour in colours.items():
            runs = [r for r in study["runs"] if r["variant"] == variant]
            for k, row in enumerate(runs):
                steps = [e["grid_steps"] for e in row["evaluations"]]
                ax.plot(steps, [e[measure] for e in row["evaluations"]], "o-", ms=3, lw=0.8, color=colour,
                        alpha=0.7, label=f"{variant} (n={len(runs)})" if k == 0 else None)
        ax.axvspan(FINAL_WINDOW[0] - EVAL_EVERY / 4, FINAL_WINDOW[-1] + EVAL_EVERY / 4, color="0.9", zorder=0)
        ax.set_xlabel("env steps")
        ax.set_ylabel(measure.replace("_", " "))
        if study["runs"]:
            ax.legend(fontsize=7)
    ax = axes[2]
    a = study["paired_log_ratio_pci_over_gated"]
    for k, key in enumerate(["final/hypervolume", "final/expected_utility", "1M/hypervolume", "1M/expected_utility"]):
        entry = a[key]
        ax.plot([k] * entry["n"], entry["log_ratios"], "o", color="0.5", ms=4)
        if entry["n"] >= 2:
            ax.errorbar([k + 0.15], [entry["mean_log_ratio"]], yerr=[[entry["mean_log_ratio"] - entry["ci95"][0]],
                        [entry["ci95"][1] - entry["mean_log_ratio"]]], fmt="s", color="k", capsize=4)
    ax.axhline(0, color="0.6", lw=0.8)
    ax.set_xticks(range(4), ["HV\nfinal", "EU\nfinal", "HV\n1M", "EU\n1M"])
    ax.set_ylabel("log(PCI / gated), per pair; mean, 95% t")
    fig.suptitle(f"{TASK}: PCI (s = {ROUTING_SCALE:g}) against the matched gate", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def write_report(root: str, seeds: list[int], docs: str | None, landed: list[dict] | None = None) -> dict:
    study = study_json(load_rows(root, seeds, landed), seeds, unfinished_runs(root, seeds, landed))
    for folder in [root] + ([docs] if docs else []):
        os.makedirs(folder, exist_ok=True)
        write_json(os.path.join(folder, "pci_vs_gated.json"), study)
        plot(study, os.path.join(folder, "pci_vs_gated.png"))
        page_path = os.path.join(folder, "mo_study.md")
        page = open(page_path).read() if os.path.isfile(page_path) else ""
        with open(page_path + ".tmp", "w") as f:
            f.write(replace_section(page, SECTION, markdown_section(study)))
        os.replace(page_path + ".tmp", page_path)
    return study


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True, help="folder of the runs (keep it outside the repository)")
    parser.add_argument("--seeds", type=int, nargs="+", default=SEEDS)
    parser.add_argument("--report-only", action="store_true", help="write the report from finished runs only")
    parser.add_argument("--docs", help="also write the JSON, figure and mo_study.md section into this folder")
    parser.add_argument("--landed", default=LANDED,
                        help="an earlier report whose finished runs count as finished (default: the repository's "
                             "docs/results/pci_vs_gated.json; '' for none)")
    args = parser.parse_args(argv)
    landed = landed_rows(args.landed)
    done = {(r["variant"], r["seed"]) for r in landed}
    if not args.report_only:
        for cell in study_cells(args.seeds):
            if (cell.name, cell.seed) in done:
                continue
            if not os.path.isfile(os.path.join(cell.folder(args.out), "result.json")):
                run_cell(cell, args.out)
                write_report(args.out, args.seeds, None, landed)  # the run folder's report is current after every run
    study = write_report(args.out, args.seeds, args.docs, landed)
    for key, entry in study["paired_log_ratio_pci_over_gated"].items():
        print(f"{key}: {interval_text(entry)}")
    return study


if __name__ == "__main__":
    main()
