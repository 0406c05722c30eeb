"""Why does PCI lose to the learned gate, and which PCI keeps its lambda-routed experts and does not? A screen of PCI
variants on mo-halfcheetah-v5, each paired by seed with the matched gate's runs of the landed PCI-against-gate study.

    python tools/studies/pci_variants.py --out ~/pchc-runs/pci-variants            # run what is missing, then report
    python tools/studies/pci_variants.py --out ~/pchc-runs/pci-variants --report-only --docs docs/results
    python tools/studies/pci_variants.py --out RUNS --steps 2000000 --variants pci-residual --seeds 0 1 2 3 4 5 6 7

The diagnosis reruns PCI at routing scale 3 (the study's PCI) to 750k env steps on seeds 2 (a high-mode run of the
study), 4 and 6 (low-mode runs), keeping each evaluation's mean return per preference, and reads the gait each run
ends with at lambda = (1, 0): its forward speed and torso pitch, and the share of steps it spends flipped onto its
back (|pitch| > 90 degrees), over the deterministic policy's evaluation episodes.

The screen trains each variant (tools/studies/mo_benchmark.py, evaluated every 250k env steps) and pairs every run with
the gate's run of the same seed at the same evaluation (1M env steps, or at 2M the mean of 1.5M, 1.75M and 2M as the
study does): the 95% Student-t interval of the mean paired log-ratio variant / gate of the hypervolume and of the
expected utility (pchc_rsl/evaluation/statistics.py); a run "in the low mode" ends below the lowest of the gate's runs
at that evaluation. The study's own PCI runs (routing scale 3) are paired the same way as the reference row. The report
writes ``pci_variants.json`` and the study's section of ``mo_study.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np
import torch

from pchc_rsl.configs.mo_gym import REFERENCE_POINTS
from pchc_rsl.envs.mo_gym import MOGymVecEnv
from pchc_rsl.evaluation.statistics import paired_log_ratio
from pchc_rsl.runners import load_checkpoint
from pchc_rsl.training import study_cells
from pchc_rsl.training.build import make_runner, restore_config
from pchc_rsl.training.study_cells import Cell, run_figure, run_row, train_folders
from pchc_rsl.utils.files import write_json

HERE = os.path.dirname(os.path.abspath(__file__))
TASK = "mo-halfcheetah-v5"
EVAL_EVERY = 250_000
SEEDS = list(range(8))
VARIANT_ARGS = {
    "pci-s0": ["--variant", "pci", "--routing-scale", "0"],
    "pci-residual": ["--variant", "pci-residual", "--routing-scale", "3", "--match-pci-parameters"],
    "pci-warmup": ["--variant", "pci-warmup", "--routing-scale", "3"],
    "pci-prior-gate": ["--variant", "pci-prior-gate", "--routing-scale", "3", "--match-pci-parameters"],
    "pci-floor": ["--variant", "pci-floor", "--routing-scale", "3"],
    "pci-s1": ["--variant", "pci", "--routing-scale", "1"],
}
"""The screen's variants and their mo_benchmark arguments (tools/studies/mo_benchmark.py, VARIANTS)."""
DESCRIPTIONS = {
    "pci-s0": "PCI with the routing off (scale 0: every expert weighted 1/5 at every lambda)",
    "pci-residual": "residual experts on a shared network every sample trains (parameters matched)",
    "pci-warmup": "routing scale warmed up from 0 to 3 over the first quarter of training",
    "pci-prior-gate": "a learned gate on top of the Beta density, starting as exact PCI (parameters matched)",
    "pci-floor": "every expert's routing weight at least 0.05",
    "pci-s1": "softer routing: scale 1 (weights 0, .1, .2, .3, .4 at lambda = (1, 0), the reverse at (0, 1))",
}
DIAGNOSIS = Cell("pci_variants", TASK, "pci-s3-750k", 0, ["--variant", "pci", "--routing-scale", "3", "--steps",
                                                          "750000", "--eval-every", str(EVAL_EVERY)])
DIAGNOSIS_SEEDS = (2, 4, 6)
FINAL_WINDOW_2M = (1_500_000, 1_750_000, 2_000_000)
MEASURES = ("hypervolume", "expected_utility")
SECTION = "pci-variants"
LANDED_GATE = os.path.join(HERE, "..", "..", "docs", "results", "pci_vs_gated.json")


def screen_cells(variants: list[str], seeds: list[int], steps: int) -> list[Cell]:
    """Seed by seed, each variant: a partial screen is paired across variants."""
    suffix = "" if steps == 1_000_000 else f"-{steps // 1000}k"
    return [Cell("pci_variants", TASK, name + suffix, seed,
                 [*VARIANT_ARGS[name], "--steps", str(steps), "--eval-every", str(EVAL_EVERY)])
            for seed in seeds for name in variants]


def diagnosis_cells() -> list[Cell]:
    return [Cell(DIAGNOSIS.group, DIAGNOSIS.task, DIAGNOSIS.name, seed, DIAGNOSIS.args) for seed in DIAGNOSIS_SEEDS]


def cell_command(cell: Cell, root: str) -> list[str]:
    return [sys.executable, os.path.join(HERE, "mo_benchmark.py"), "--task", cell.task, "--seed", str(cell.seed),
            "--out", cell.folder(root), *cell.args]


def cell_row(cell: Cell, root: str) -> dict | None:
    """The finished cell's row (named as the cell), or None."""
    path = os.path.join(cell.folder(root), "result.json")
    if not os.path.isfile(path):
        return None
    with open(path) as f:
        return {**run_row(json.load(f)), "variant": cell.name}


def landed_rows(path: str, variant: str = "gated") -> list[dict]:
    """One variant's runs of the landed PCI-against-gate study: the gate's, or PCI's at routing scale 3 ("pci")."""
    with open(path) as f:
        study = json.load(f)
    return [r for r in study["runs"] if r["variant"] == variant]


def screen_figures(steps: int) -> tuple[int, ...]:
    """The grid points whose mean is a run's figure: 1M at the screen's budget, the study's final window at 2M."""
    return (1_000_000,) if steps == 1_000_000 else FINAL_WINDOW_2M


def compare(rows: list[dict], gates: list[dict], grid: tuple[int, ...]) -> dict:
    """Per measure: the paired log-ratio of the rows against the gate, and how many rows lie below every gate run."""
    out = {}
    for measure in MEASURES:
        gate = {g["seed"]: run_figure(g, measure, grid) for g in gates}
        pairs = [(r["seed"], run_figure(r, measure, grid), gate.get(r["seed"])) for r in rows]
        pairs = [p for p in pairs if p[1] is not None and p[2] is not None]
        result = paired_log_ratio([p[1] for p in pairs], [p[2] for p in pairs])
        lowest_gate = min((v for v in gate.values() if v is not None), default=math.nan)
        result.update(seeds=[p[0] for p in pairs], figures=[p[1] for p in pairs],
                      below_every_gate_run=sum(p[1] < lowest_gate for p in pairs), lowest_gate=lowest_gate)
        out[measure] = result
    return out


def returns_at(row: dict, grid_steps: int) -> list[list[float]] | None:
    """The run's mean return per evaluation preference at that grid point."""
    return next((e.get("mean_returns") for e in row["evaluations"] if e["grid_steps"] == grid_steps), None)


def gait_at(folder: str, preference: tuple[float, float], episodes: int = 5, seed: int = 10_000) -> dict:
    """The final policy of a run folder, deterministic, at ``preference`` on the raw env: forward speed (m/s), mean
    torso pitch (deg), and the share of steps flipped (|pitch| > 90 deg), over ``episodes`` seeded episodes."""
    final = [os.path.join(t, "model_final.pt") for t in train_folders(folder)]
    path = next(p for p in reversed(final) if os.path.isfile(p))
    cfg = restore_config(load_checkpoint(path)["config"])
    cfg.num_envs = 1
    runner = make_runner(cfg)
    runner.load(path)
    policy = runner.get_inference_policy()
    env_cfg = cfg.env
    env_cfg.reward_scale = 1.0
    env = MOGymVecEnv(env_cfg, episodes, "cpu", seed)
    env.set_preference(preference)
    obs = env.get_observations()
    pitch, speed = [], []
    running = np.ones(episodes, dtype=bool)
    with torch.inference_mode():
        while running.any():
            obs, _, dones, _ = env.step(policy(obs))
            for i, raw in enumerate(env.envs):
                if running[i]:
                    data = raw.unwrapped.data
                    pitch.append(float(data.qpos[2]))
                    speed.append(float(data.qvel[0]))
            running &= ~dones.numpy().astype(bool)
    env.close()
    pitch_deg = np.degrees(np.array(pitch))
    return {"forward_speed": float(np.mean(speed)), "pitch_deg": float(np.mean(pitch_deg)),
            "flipped_share": float(np.mean(np.abs(pitch_deg) > 90.0))}


def study_json(root: str, variants: list[str], seeds: list[int], steps: int, gates: list[dict],
               gaits: bool = True, landed_pci: list[dict] = ()) -> dict:
    grid = screen_figures(steps)
    diagnosis = []
    for cell in diagnosis_cells():
        row = cell_row(cell, root)
        if row is not None:
            row["gait_at_1_0"] = gait_at(cell.folder(root), (1.0, 0.0)) if gaits else None
            diagnosis.append(row)
    screen = {}
    if landed_pci:  # the reference every variant changes: the study's PCI, its runs at the same evaluations
        screen["pci"] = {"description": "PCI as in the paired study (routing scale 3; its runs there)",
                         "runs": list(landed_pci), "against_gate": compare(list(landed_pci), gates, grid)}
    for name in variants:
        rows = [r for c in screen_cells([name], seeds, steps) if (r := cell_row(c, root)) is not None]
        if rows:
            screen[name] = {"description": DESCRIPTIONS[name], "runs": rows, "against_gate": compare(rows, gates, grid)}
    gate_summary = {m: sorted(v for g in gates if (v := run_figure(g, m, grid)) is not None) for m in MEASURES}
    return {"task": TASK, "steps": steps, "figure_grid": list(grid), "reference_point": list(REFERENCE_POINTS[TASK]),
            "gate_runs": gate_summary, "diagnosis": diagnosis, "screen": screen,
            "commands": {name: " ".join(["python tools/studies/mo_benchmark.py --task", TASK, "--seed SEED --out",
                                         f"RUNS/{TASK}/{name}_seedSEED", *VARIANT_ARGS[name], "--steps", str(steps),
                                         "--eval-every", str(EVAL_EVERY)]) for name in variants}}


def interval(a: dict) -> str:
    if a["n"] < 2:
        return f"n = {a['n']}"
    low, high = a["ratio_ci95"]
    return f"{a['ratio']:.2f} [{low:.2f}, {high:.2f}], n = {a['n']}"


def markdown_section(study: dict) -> str:
    steps = study["steps"]
    at = "1M env steps" if steps == 1_000_000 else "the mean of 1.5M, 1.75M and 2M env steps"
    lines = [f"<!-- {SECTION}:start -->", "## Why PCI's runs split, and PCI variants against the gate", ""]
    if study["diagnosis"]:
        lines += ["**Diagnosis.** PCI at routing scale 3, rerun to 750k env steps (seed 2 ended in the high mode of "
                  "the paired study, seeds 4 and 6 in the low one): mean return (forward, energy) per preference at "
                  "750k, and the gait each run ends with at lambda = (1, 0) (deterministic policy, 5 episodes).", ""]
        prefs = study["diagnosis"][0]["preferences"]
        lines.append("| seed | HV at 750k | " + " | ".join(f"({p[0]:g}, {p[1]:g})" for p in prefs[:6]) +
                     " | forward speed at (1, 0) | torso pitch | steps flipped | routing mass per expert |")
        lines.append("|---|---|" + "---|" * min(6, len(prefs)) + "---|---|---|---|")
        for row in study["diagnosis"]:
            returns = returns_at(row, 750_000) or []
            hv = run_figure(row, "hypervolume", (750_000,))
            gait = row.get("gait_at_1_0") or {}
            mass = ", ".join(f"{m:.2f}" for m in row.get("routing_mass_last_tenth") or [])
            lines.append(f"| {row['seed']} | {hv:.3g} | " + " | ".join(f"{r[0]:.0f}, {r[1]:.0f}" for r in returns[:6])
                         + f" | {gait.get('forward_speed', math.nan):.2f} m/s | {gait.get('pitch_deg', math.nan):.0f}"
                         f" deg | {100 * gait.get('flipped_share', math.nan):.0f}% | {mass} |")
        lines.append("")
    if study["screen"]:
        gate = study["gate_runs"]
        lines += [f"**Screen** at {at}, each run paired with the matched gate's run of its seed (the gate's "
                  f"hypervolume over its runs: {min(gate['hypervolume']):.3g} to {max(gate['hypervolume']):.3g}). "
                  "Ratio variant / gate, mean of the paired log-ratios with its 95% interval; low mode: runs below "
                  "every gate run.", "",
                  "| variant | what it changes | HV ratio [95% CI] | EU ratio [95% CI] | low mode (HV) | "
                  "return at (1, 0), mean | routing mass per expert, mean |",
                  "|---|---|---|---|---|---|---|"]
        grid = study["figure_grid"][-1]
        for name, entry in study["screen"].items():
            hv, eu = entry["against_gate"]["hypervolume"], entry["against_gate"]["expected_utility"]
            forward = [r[0][0] for row in entry["runs"] if (r := returns_at(row, grid))]
            masses = [row["routing_mass_last_tenth"] for row in entry["runs"] if row.get("routing_mass_last_tenth")]
            mass = ", ".join(f"{m:.2f}" for m in np.mean(masses, axis=0)) if masses else "-"
            forward = f"{np.mean(forward):.0f}" if forward else "-"
            lines.append(f"| {name} | {entry['description']} | {interval(hv)} | {interval(eu)} | "
                         f"{hv['below_every_gate_run']} of {hv['n']} | {forward} | {mass} |")
        lines.append("")
    lines += ["Reproduce: `python tools/studies/pci_variants.py --out RUNS` (resumable; one cell: the commands in "
              "`pci_variants.json`), then `--report-only --docs docs/results`.", f"<!-- {SECTION}:end -->", ""]
    return "\n".join(lines)


def replace_section(page: str, body: str) -> str:
    start, end = f"<!-- {SECTION}:start -->", f"<!-- {SECTION}:end -->\n"
    if start in page:
        return page[: page.index(start)] + body + page[page.index(end) + len(end):]
    return page.rstrip("\n") + "\n\n" + body


def write_report(root: str, variants: list[str], seeds: list[int], steps: int, docs: str | None, gates: list[dict],
                 gaits: bool = True, landed_pci: list[dict] = ()) -> dict:
    study = study_json(root, variants, seeds, steps, gates, gaits, landed_pci)
    name = "pci_variants.json" if steps == 1_000_000 else f"pci_variants_{steps // 1000}k.json"
    for folder in [root] + ([docs] if docs else []):
        os.makedirs(folder, exist_ok=True)
        write_json(os.path.join(folder, name), study)
        page_path = os.path.join(folder, "mo_study.md")
        page = open(page_path).read() if os.path.isfile(page_path) else ""
        with open(page_path + ".tmp", "w") as f:
            f.write(replace_section(page, markdown_section(study)))
        os.replace(page_path + ".tmp", page_path)
    return study


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True, help="folder of the runs (keep it outside the repository)")
    parser.add_argument("--variants", nargs="+", default=list(VARIANT_ARGS), choices=list(VARIANT_ARGS))
    parser.add_argument("--seeds", type=int, nargs="+", default=SEEDS)
    parser.add_argument("--steps", type=int, default=1_000_000, choices=(1_000_000, 2_000_000))
    parser.add_argument("--no-diagnosis", action="store_true", help="skip the 750k diagnosis runs")
    parser.add_argument("--report-only", action="store_true", help="write the report from finished runs only")
    parser.add_argument("--docs", help="also write the JSON and the mo_study.md section into this folder")
    parser.add_argument("--gate", default=LANDED_GATE, help="the PCI-against-gate report whose gate runs pair")
    args = parser.parse_args(argv)
    gates, landed_pci = landed_rows(args.gate), landed_rows(args.gate, "pci")
    if not args.report_only:
        cells = ([] if args.no_diagnosis else diagnosis_cells()) + screen_cells(args.variants, args.seeds, args.steps)
        for cell in cells:
            if not os.path.isfile(os.path.join(cell.folder(args.out), "result.json")):
                study_cells.run_cell(cell, args.out, [*cell_command(cell, args.out), "--resume"])
    study = write_report(args.out, args.variants, args.seeds, args.steps, args.docs, gates, landed_pci=landed_pci)
    for name, entry in study["screen"].items():
        print(f"{name}: HV {interval(entry['against_gate']['hypervolume'])}; EU "
              f"{interval(entry['against_gate']['expected_utility'])}")
    return study


if __name__ == "__main__":
    main()
