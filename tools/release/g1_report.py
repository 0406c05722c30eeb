"""The model cards of the shipped G1 policies, docs/results/g1_walk.md and docs/results/g1_fall_recovery.md.

    pchc-eval policies/g1_walk.pt --num-envs 256 --episodes 1 --switch --output EVAL/walk
    pchc-eval policies/g1_walk.pt --robustness --num-envs 32 --episodes 1 --output EVAL/walk-robustness
    pchc-eval policies/g1_fall_recovery.pt --num-envs 256 --episodes 1 --output EVAL/fall
    pchc-eval policies/g1_fall_recovery.pt --robustness --num-envs 32 --episodes 1 --output EVAL/fall-robustness
    python tools/release/g1_report.py --walk EVAL/walk --walk-robustness EVAL/walk-robustness \
        --fall EVAL/fall --fall-robustness EVAL/fall-robustness --docs docs/results

A card is a hand-written head (what the policy is, its recipe and lineage as commands, sim-to-sim, what it does
not do yet), kept above the marker line, and generated sections below it: the paper's table beside ours with the
units of each, the targets met and not met, the Pareto front, the deployment shifts as a heatmap and tables, claim
(d), and training curves. A generated section whose inputs are not given is kept as it was, and a section made from
more episodes per preference is only replaced with --force. --claim-d takes a pchc-eval folder of a PCHC walker
(first checkpoint) and fixed-preference walkers (pchc-train --fixed-preference) and puts each fixed one beside PCHC
at its preference; --claim-d-fall does the same for fall-recovery policies. --walk-runs / --fall-runs (run folders
joined by '+') add training curves from the runs' TensorBoard events.

"Grows" has one meaning here: larger at each of the five preferences than at the one before, from (1, 0) to (0, 1).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
from dataclasses import dataclass

import numpy as np

from pchc_rsl.evaluation import FALL_RECOVERY_EVALUATION, WALK_EVALUATION, TaskEvaluation, format_metric, front_points
from pchc_rsl.evaluation.training_plots import plot_training, run_curves, summary_table

PAPER_TABLE_II = {  # preference (disturbance, stride) -> (avg. stride m, trajectory deviation m)
    (0.0, 1.0): (0.79, 0.85),
    (0.25, 0.75): (0.72, 0.51),
    (0.5, 0.5): (0.67, 0.33),
    (0.75, 0.25): (0.55, 0.29),
    (1.0, 0.0): (0.42, 0.23),  # printed as (0.10, 0.00), a typo for (1.00, 0.00)
}
PAPER_TABLE_I = {  # preference (energy, disturbance) -> (energy overall, COM displacement m, success %)
    (1.0, 0.0): (463.45, 1.82, 62.24),
    (0.75, 0.25): (480.58, 1.73, 67.95),
    (0.5, 0.5): (517.90, 1.62, 75.73),
    (0.25, 0.75): (583.31, 1.12, 91.95),
    (0.0, 1.0): (666.24, 0.75, 96.56),
}
GENERATED_MARKER = "<!-- Below: written by tools/release/g1_report.py; edit the text above. -->"
CARDS = {"walk": ("g1_walk.md", "# The G1 walker (`policies/g1_walk.*`)"),
         "fall": ("g1_fall_recovery.md", "# The G1 fall-recovery policy (`policies/g1_fall_recovery.*`)")}
"""card -> (file in --docs, the title of a new card)."""
GROWS = ("'Grows' means larger at each preference than at the one before, from (1, 0) to (0, 1); 'shrinks' the "
         "reverse.")
WALK_FALLS_MAX = 5.0
WALK_MIN_EPISODES = 256
FALL_MILD_SUCCESS_MIN = 80.0
FALL_STRONG_SUCCESS_AT_END_MIN = 90.0


def kept_text(path: str, title: str) -> str:
    """The hand-written part of an existing card (everything above the marker), or ``title`` for a new one."""
    if os.path.exists(path):
        with open(path) as f:
            text = f.read()
        if GENERATED_MARKER in text:
            return text[: text.index(GENERATED_MARKER)].rstrip()
    return title


def generated_sections(path: str) -> dict[str, str]:
    """The generated part of an existing card by its '## ' titles (title -> the section's lines after it)."""
    if not os.path.exists(path):
        return {}
    with open(path) as f:
        text = f.read()
    if GENERATED_MARKER not in text:
        return {}
    sections, title = {}, None
    for line in text.split(GENERATED_MARKER, 1)[1].splitlines():
        if line.startswith("## "):
            title = line[3:].strip()
            sections[title] = []
        elif title is not None:
            sections[title].append(line)
    return {k: "\n".join(v).strip("\n") for k, v in sections.items()}


def subsection(text: str, title: str) -> str | None:
    """A '### title' subsection of a section's text, up to the next '###' heading; None without it."""
    lines, inside, out = text.splitlines(), False, []
    for line in lines:
        if line.startswith("### "):
            inside = line[4:].strip() == title
            if inside:
                out.append(line)
            continue
        if inside:
            out.append(line)
    return "\n".join(out).strip("\n") or None


EPISODES_NOTE = "<!-- episodes per preference: {} -->"


def episodes_of(text: str) -> int | None:
    """The episode count a section recorded (EPISODES_NOTE), None for sections written before it was recorded."""
    prefix = EPISODES_NOTE.split("{}")[0]
    for line in text.splitlines():
        if line.startswith(prefix):
            return int(line[len(prefix):].split()[0])
    return None


def load_results(folder: str) -> dict:
    with open(os.path.join(folder, "results.json")) as f:
        return json.load(f)


def rows_by_preference(result: dict) -> dict[tuple[float, ...], dict]:
    return {tuple(round(x, 4) for x in row["preference"]): row for row in result["rows"]}


def value(row: dict, key: str) -> float:
    v = row["metrics"].get(key)
    return math.nan if v is None else float(v)


def cell(row: dict, key: str, digits: int = 2) -> str:
    """'mean ± half-width' (or 'mean [low, high]' for rates) from a pchc-eval row; 'n/a' where undefined."""
    return format_metric(value(row, key), row["metrics"].get(f"{key}_ci95"), key, digits)


def increasing(values: list[float]) -> bool:
    """Strictly increasing and all defined: the order a table's column must follow from (1, 0) to (0, 1)."""
    return all(v == v for v in values) and all(b > a for a, b in zip(values, values[1:]))


def ends_note(values: list[float]) -> str:
    """For a column that does not grow at every step but ends higher than it starts: says so (an order of the
    ends only, which the target does not count)."""
    if increasing(values) or not all(v == v for v in values) or not values[-1] > values[0]:
        return ""
    return "; higher at (0, 1) than at (1, 0), not at every step"


def verdict(ok: bool) -> str:
    return "met" if ok else "**not met**"


def preference_label(lam) -> str:
    return "(" + ", ".join(f"{x:.2f}" for x in lam) + ")"


GAIT_COLUMNS = (("forward_step", "Forward step (m)"), ("side_step", "Side step (m)"),
                ("cadence", "Cadence (1/s per foot)"), ("air_time", "Air time, median (s)"),
                ("backward_touchdowns", "Backward touchdowns (%)"), ("forward_speed", "Forward speed (m/s)"),
                ("strong/fall_rate", "Falls, strong pushes (%)"))
FOOT_COLUMNS = (("air_time_left", "Swing left (s)"), ("air_time_right", "Swing right (s)"),
                ("forward_step_left", "Step left (m)"), ("forward_step_right", "Step right (m)"),
                ("heading_drift_median", "Heading drift, median (deg)"),
                ("heading_drift_p90", "Heading drift, p90 (deg)"), ("lateral_drift", "Lateral drift (m)"))
POSTURE_COLUMNS = (("base_height", "Pelvis height (m)"), ("knee_flexion", "Knee flexion (deg)"),
                   ("knee_torque_rms", "Knee torque RMS (Nm)"))
POSTURE_NOTE = ("Posture, same episodes (each episode's mean, then the mean over episodes): the G1's default pose "
                "stands with the pelvis at 0.76 m, the LAFAN1 walk keeps it at 0.77 m with the knees at 34 +- 17 "
                "deg; the knee motors are rated 139 Nm.")
PELVIS_MIN, KNEE_FLEXION_MAX = 0.70, 55.0
SYMMETRY_MAX = 1.2
HEADING_MEDIAN_MAX, HEADING_P90_MAX = 5.0, 10.0
SPEED_RANGE = (0.4, 0.6)
STEP_GROWTH_MIN = 1.5
YAW_RATE_ERROR_MAX, LATERAL_ERROR_MAX, STANDING_FALLS_MAX = 0.15, 0.1, 2.0


def left_right_ratio(row: dict, left: str, right: str) -> float:
    """The larger of a left and a right figure over the smaller (1: symmetric)."""
    pair = sorted([value(row, left), value(row, right)])
    return pair[1] / pair[0] if pair[0] > 0 else math.nan


def gait_targets(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """The steerable walker's gait targets, from rows ordered (1, 0) -> (0, 1); only those the rows measured."""
    targets = []
    if all("air_time_left" in row["metrics"] for row in rows):
        swing = [left_right_ratio(r, "air_time_left", "air_time_right") for r in rows]
        step = [left_right_ratio(r, "forward_step_left", "forward_step_right") for r in rows]
        worst = max(swing + step)
        targets.append((f"left/right swing time and forward step within {SYMMETRY_MAX:g}x at every preference",
                        worst <= SYMMETRY_MAX, "swing " + ", ".join(f"{x:.2f}" for x in swing) + "; step "
                        + ", ".join(f"{x:.2f}" for x in step)))
    if all("heading_drift_median" in row["metrics"] for row in rows):
        median = [value(r, "heading_drift_median") for r in rows]
        p90 = [value(r, "heading_drift_p90") for r in rows]
        heading_ok = max(median) <= HEADING_MEDIAN_MAX and max(p90) <= HEADING_P90_MAX
        targets.append((f"heading drift over an episode: median <= {HEADING_MEDIAN_MAX:g}, 90th percentile <= "
                        f"{HEADING_P90_MAX:g} degrees", heading_ok,
                        "median " + ", ".join(f"{x:.1f}" for x in median) + "; p90 "
                        + ", ".join(f"{x:.1f}" for x in p90) + " degrees"))
    if all("base_height" in row["metrics"] and "knee_flexion" in row["metrics"] for row in rows):
        height = [value(r, "base_height") for r in rows]
        knee = [value(r, "knee_flexion") for r in rows]
        targets.append((f"upright: pelvis >= {PELVIS_MIN:g} m and knee flexion <= {KNEE_FLEXION_MAX:g} deg at every "
                        "preference", min(height) >= PELVIS_MIN and max(knee) <= KNEE_FLEXION_MAX,
                        "pelvis " + ", ".join(f"{h:.2f}" for h in height) + " m; knees "
                        + ", ".join(f"{k:.0f}" for k in knee) + " deg"))
    if not all("forward_speed" in row["metrics"] and "forward_step" in row["metrics"] for row in rows):
        return targets
    speed = [value(r, "forward_speed") for r in rows]
    targets.append((f"forward speed {SPEED_RANGE[0]:g}-{SPEED_RANGE[1]:g} m/s at every preference (told 0.5)",
                    all(SPEED_RANGE[0] <= v <= SPEED_RANGE[1] for v in speed),
                    ", ".join(f"{v:.2f}" for v in speed) + " m/s"))
    steps = [value(r, "forward_step") for r in rows]
    growth = steps[-1] / steps[0] if steps[0] > 0 else math.nan
    targets.append((f"forward step from (1, 0) to (0, 1) grows by >= {STEP_GROWTH_MIN:g}x", growth >= STEP_GROWTH_MIN,
                    f"{steps[0]:.2f} -> {steps[-1]:.2f} m ({growth:.2f}x)"))
    return targets


def steering_targets(report: dict) -> list[tuple[str, bool, str]]:
    """Yaw-rate and lateral-speed errors under the steering conditions and falls told to stand, from a pchc-eval
    --robustness report of a walker (conditions it did not run are left out)."""
    from pchc_rsl.evaluation.robustness import STEERING

    by_condition: dict[str, list[dict]] = {}
    for row in report["rows"]:
        by_condition.setdefault(row["condition"], []).append(row["metrics"])
    targets = []
    for key, limit, unit, wanted in (("yaw_rate_error", YAW_RATE_ERROR_MAX, "rad/s", "turn"),
                                     ("lateral_speed_error", LATERAL_ERROR_MAX, "m/s", "side step")):
        names = [name for name, *_ in STEERING if name.startswith(wanted) and name in by_condition]
        if not names:
            continue
        errors = {name: [m.get(key) for m in by_condition[name]] for name in names}
        worst = max((e for values in errors.values() for e in values if e is not None), default=math.nan)
        targets.append((f"{key.replace('_', ' ')} <= {limit:g} {unit} at every preference ({', '.join(names)})",
                        worst <= limit, "; ".join(f"{name}: " + ", ".join("n/a" if e is None else f"{e:.2f}"
                                                                              for e in values)
                                                  for name, values in errors.items())))
    if "command 0 m/s" in by_condition:
        falls = [m.get("fall_rate") for m in by_condition["command 0 m/s"]]
        episodes = min(row["episodes"] for row in report["rows"] if row["condition"] == "command 0 m/s")
        targets.append((f"told to stand: falls <= {STANDING_FALLS_MAX:g}% at every preference",
                        all(f is not None and f <= STANDING_FALLS_MAX for f in falls),
                        ", ".join("n/a" if f is None else f"{f:.1f}" for f in falls)
                        + f"% ({episodes} episodes per preference)"))
    return targets


def walk_section(results: dict) -> tuple[list[str], list[tuple[str, bool, str]]]:
    """Table II beside the paper's and the walking targets, for the first checkpoint (the PCHC policy); further
    checkpoints (fixed-preference baselines) get rows of their own."""
    lines = ["| Policy | lambda (disturbance, stride) | Avg. stride (m) | paper (m) | Traj. deviation (m) | paper (m) "
             "| Falls (%) | Episodes |",
             "|---|---|---|---|---|---|---|---|"]
    for result in results["results"]:
        for lam, row in sorted(rows_by_preference(result).items(), reverse=True):
            paper = PAPER_TABLE_II.get(lam, (math.nan, math.nan))
            lines.append(f"| {result['name']} | {preference_label(lam)} | {cell(row, 'stride_length')} | "
                         f"{paper[0]:.2f} | {cell(row, 'push_deviation')} | {paper[1]:.2f} | "
                         f"{cell(row, 'fall_rate')} | {row['episodes']} |")
    main = results["results"][0]
    rows = [row for _, row in sorted(rows_by_preference(main).items(), reverse=True)]  # (1, 0) -> (0, 1)
    gait = [(key, title) for key, title in GAIT_COLUMNS if any(key in row["metrics"] for row in rows)]
    if gait:  # what the paper's table does not show: the gait, and falls under the strong pushes
        lines += ["", "The gait behind the table (not in the paper), same episodes:", "",
                  "| lambda (disturbance, stride) | " + " | ".join(title for _, title in gait) + " |",
                  "|---|" + "---|" * len(gait)]
        for row in rows:
            lines.append(f"| {preference_label(row['preference'])} | "
                         + " | ".join(cell(row, key) for key, _ in gait) + " |")
    feet = [(key, title) for key, title in FOOT_COLUMNS if any(key in row["metrics"] for row in rows)]
    if feet:
        lines += ["", "Each foot, and the heading over an episode (swing and step: touchdowns after the first 0.5 s):",
                  "", "| lambda (disturbance, stride) | " + " | ".join(title for _, title in feet) + " |",
                  "|---|" + "---|" * len(feet)]
        for row in rows:
            lines.append(f"| {preference_label(row['preference'])} | "
                         + " | ".join(cell(row, key, 1 if key.startswith("heading") else 2) for key, _ in feet) + " |")
    posture = [(key, title) for key, title in POSTURE_COLUMNS if any(key in row["metrics"] for row in rows)]
    if posture:
        lines += ["", POSTURE_NOTE, "", "| lambda (disturbance, stride) | "
                  + " | ".join(title for _, title in posture) + " |", "|---|" + "---|" * len(posture)]
        for row in rows:
            lines.append(f"| {preference_label(row['preference'])} | "
                         + " | ".join(cell(row, key, 2 if key == "base_height" else 1) for key, _ in posture) + " |")
    falls = [value(r, "fall_rate") for r in rows]
    episodes = min(r["episodes"] for r in rows)
    strides = [value(r, "stride_length") for r in rows]
    deviations = [value(r, "push_deviation") for r in rows]
    targets = [
        (f"falls <= {WALK_FALLS_MAX:g}% at every preference, >= {WALK_MIN_EPISODES} episodes each",
         max(falls) <= WALK_FALLS_MAX and episodes >= WALK_MIN_EPISODES,
         f"falls {', '.join(f'{f:.1f}' for f in falls)}% from (1, 0) to (0, 1); {episodes} episodes per preference"),
        ("stride grows from (1, 0) to (0, 1)", increasing(strides),
         ", ".join(f"{s:.3f}" for s in strides) + " m" + ends_note(strides)),
        ("deviation grows from (1, 0) to (0, 1)", increasing(deviations),
         ", ".join(f"{d:.3f}" for d in deviations) + " m" + ends_note(deviations)),
    ]
    targets += gait_targets(rows)
    force_lines, force_targets = force_section(rows, WALK_FORCE_COLUMNS, WALK_FORCE_NOTE)
    lines += force_lines
    targets += force_targets
    switching = results.get("switching")
    if switching is not None:
        settle = switching["settle_time_s"]
        settle = "n/a" if settle is None else f"{settle:.2f} s"
        targets.append(("switching (0, 1) -> (1, 0) mid-episode without a fall", switching["falls"] == 0,
                        f"{switching['falls']} falls over the envs; the objectives settle {settle} after the switch"))
    else:
        targets.append(("switching (0, 1) -> (1, 0) mid-episode without a fall", False, "not measured (no --switch)"))
    return lines, targets


WALK_FORCE_COLUMNS = (("force-mild/fall_rate", "Falls, 300-600 N torso/pelvis (%)"),
                      ("force-mild/push_deviation", "Traj. deviation, 300-600 N (m)"),
                      ("force-legs/fall_rate", "Falls, 100-300 N legs (%)"),
                      ("force-legs/push_deviation", "Traj. deviation, 100-300 N legs (m)"))
WALK_FORCE_NOTE = ("Pushes as forces (docs/evaluation.md, 'Pushes as forces'): 300-600 N for 0.08 s on the torso or "
                   "pelvis, and 100-300 N for 0.08 s on a knee or ankle, every 3 s in a random direction, same "
                   "episodes count:")
FALL_FORCE_COLUMNS = (("force-mild/com_displacement", "COM displ., 300-600 N (m)"),
                      ("force-mild/success", "Success, 300-600 N (%)"),
                      ("force-strong/success", "Success, 700-1000 N (%)"))
FALL_FORCE_NOTE = ("Pushes as forces (docs/evaluation.md, 'Pushes as forces'): 300-600 N and 700-1000 N for 0.1 s on "
                   "the torso or pelvis once the robot stands, every 3 s in a random direction, same episodes count:")
WALK_FORCE_FALLS_MAX = 5.0


def force_section(rows: list[dict], columns, note: str) -> tuple[list[str], list[tuple[str, bool, str]]]:
    """The force presets' table, and their targets: few falls at every preference on the walker, and the
    disturbance end best under them (walker: falls and deviation grow towards the stride end; fall recovery:
    success grows, the COM displacement shrinks towards the disturbance end)."""
    shown = [(key, title) for key, title in columns if any(key in row["metrics"] for row in rows)]
    if not shown:
        return [], []
    lines = ["", note, "", "| lambda | " + " | ".join(title for _, title in shown) + " |",
             "|---|" + "---|" * len(shown)]
    for row in rows:
        lines.append(f"| {preference_label(row['preference'])} | " + " | ".join(cell(row, k) for k, _ in shown) + " |")
    keys = {key for key, _ in shown}
    targets = []
    if "force-mild/fall_rate" in keys:  # walking: lambda = (disturbance, stride)
        falls = [value(r, "force-mild/fall_rate") for r in rows]
        deviation = [value(r, "force-mild/push_deviation") for r in rows]
        targets += [
            (f"falls <= {WALK_FORCE_FALLS_MAX:g}% at every preference, 300-600 N on the torso or pelvis",
             max(falls) <= WALK_FORCE_FALLS_MAX, ", ".join(f"{f:.1f}" for f in falls) + "%"),
            ("falls grow from (1, 0) to (0, 1), 300-600 N", increasing(falls) or all(f == 0 for f in falls),
             ", ".join(f"{f:.1f}" for f in falls) + "%"),
            ("deviation grows from (1, 0) to (0, 1), 300-600 N", increasing(deviation),
             ", ".join(f"{d:.3f}" for d in deviation) + " m" + ends_note(deviation)),
        ]
    if "force-strong/success" in keys:  # fall recovery: lambda = (energy, disturbance)
        strong = [value(r, "force-strong/success") for r in rows]
        com = [value(r, "force-mild/com_displacement") for r in rows]
        targets += [
            ("success grows from (1, 0) to (0, 1), 700-1000 N", increasing(strong),
             ", ".join(f"{x:.1f}" for x in strong) + "%" + ends_note(strong)),
            ("COM displacement shrinks from (1, 0) to (0, 1), 300-600 N", increasing([-c for c in com]),
             ", ".join(f"{c:.3f}" for c in com) + " m" + ends_note([-c for c in com])),
        ]
    return lines, targets


def fall_section(results: dict) -> tuple[list[str], list[tuple[str, bool, str]]]:
    lines = ["| Policy | lambda (energy, disturbance) | Energy overall (J/s) | paper (J) | Torque overall (Nm) "
             "| COM displ., mild (m) | paper (m) | Success, mild (%) | Success, strong (%) | paper (%) | Episodes |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for result in results["results"]:
        for lam, row in sorted(rows_by_preference(result).items(), reverse=True):
            paper = PAPER_TABLE_I.get(lam, (math.nan,) * 3)
            lines.append(f"| {result['name']} | {preference_label(lam)} | {cell(row, 'energy_overall', 1)} | "
                         f"{paper[0]:.1f} | {cell(row, 'torque_overall', 1)} | {cell(row, 'mild/com_displacement')} | "
                         f"{paper[1]:.2f} | {cell(row, 'mild/success')} | {cell(row, 'strong/success')} | "
                         f"{paper[2]:.1f} | {row['episodes']} |")
    main = results["results"][0]
    rows = [row for _, row in sorted(rows_by_preference(main).items(), reverse=True)]  # (1, 0) -> (0, 1)
    mild = [value(r, "mild/success") for r in rows]
    strong = [value(r, "strong/success") for r in rows]
    energy = [value(r, "energy_overall") for r in rows]
    com = [value(r, "mild/com_displacement") for r in rows]
    targets = [
        (f"success >= {FALL_MILD_SUCCESS_MIN:g}% at every preference, mild pushes",
         min(mild) >= FALL_MILD_SUCCESS_MIN, ", ".join(f"{s:.1f}" for s in mild) + "% from (1, 0) to (0, 1)"),
        ("success grows from (1, 0) to (0, 1), strong pushes", increasing(strong),
         ", ".join(f"{s:.1f}" for s in strong) + "%"),
        (f"success >= {FALL_STRONG_SUCCESS_AT_END_MIN:g}% at (0, 1), strong pushes",
         strong[-1] >= FALL_STRONG_SUCCESS_AT_END_MIN, f"{strong[-1]:.1f}%"),
        ("energy grows from (1, 0) to (0, 1)", increasing(energy),
         ", ".join(f"{e:.1f}" for e in energy) + " J/s" + ends_note(energy)),
        ("COM displacement shrinks from (1, 0) to (0, 1)", increasing([-c for c in com]),
         ", ".join(f"{c:.3f}" for c in com) + " m" + ends_note([-c for c in com])),
    ]
    force_lines, force_targets = force_section(rows, FALL_FORCE_COLUMNS, FALL_FORCE_NOTE)
    return lines + force_lines, targets + force_targets


def env_steps(checkpoint: str) -> int | None:
    """Env steps behind a checkpoint: (iterations done) x envs x steps per env; None if the file is gone, or if
    its run, or a run it was resumed from, started with ``--init-from``: such a run counts its iterations from 0,
    so they say nothing of the steps before it."""
    if not checkpoint:
        return None
    if not os.path.exists(checkpoint):
        print(f"g1_report: {checkpoint} is not here, so its env steps are left out (pchc-eval records a checkpoint "
              "relative to the folder it ran in: run this from there).", file=sys.stderr)
        return None
    import torch

    saved = torch.load(checkpoint, map_location="cpu", weights_only=True)
    config, seen = saved["config"], {os.path.abspath(checkpoint)}
    while not config.get("initialised_from"):
        resumed = config.get("resumed_from")
        if not resumed:
            return (saved["iter"] + 1) * saved["config"]["num_envs"] * saved["config"]["runner"]["num_steps_per_env"]
        if os.path.abspath(resumed) in seen or not os.path.exists(resumed):
            return None
        seen.add(os.path.abspath(resumed))
        config = torch.load(resumed, map_location="cpu", weights_only=True)["config"]
    return None


def dominates(a, b) -> bool:
    """Pareto dominance of two points in an evaluation's 'more is better' front coordinates."""
    return bool((a >= b).all() and (a > b).any())


@dataclass(frozen=True)
class ClaimD:
    """One task's claim (d) section: its title, what its policies are called, the columns put side by side and the
    differences (PCHC minus fixed) the verdict line gives, each as (label, metric key, format)."""

    title: str
    policy: str
    policies: str
    plot: str
    evaluation: TaskEvaluation
    columns: tuple[tuple[str, str, int], ...]
    differences: tuple[tuple[str, str, str], ...]


CLAIM_D = {
    "walk": ClaimD("Claim (d): one PCHC walker against fixed-preference walkers, same budget each", "walker",
                   "walkers", "g1_claim_d_pareto.png", WALK_EVALUATION,
                   (("stride_length", "Avg. stride (m)", 2), ("push_deviation", "Traj. deviation (m)", 2),
                    ("fall_rate", "Falls (%)", 2)),
                   (("stride", "stride_length", "{:+.3f} m"), ("deviation", "push_deviation", "{:+.3f} m"),
                    ("falls", "fall_rate", "{:+.1f} points"))),
    "fall": ClaimD("Claim (d): one PCHC fall-recovery policy against fixed-preference policies, same budget each",
                   "fall-recovery policy", "fall-recovery policies", "g1_fall_claim_d_pareto.png",
                   FALL_RECOVERY_EVALUATION,
                   (("energy_overall", "Energy overall (J/s)", 1), ("mild/com_displacement", "COM displ., mild (m)", 2),
                    ("mild/success", "Success, mild (%)", 2), ("strong/success", "Success, strong (%)", 2)),
                   (("energy", "energy_overall", "{:+.1f} J/s"), ("COM displacement", "mild/com_displacement",
                                                                  "{:+.3f} m"),
                    ("mild success", "mild/success", "{:+.1f} points"),
                    ("strong success", "strong/success", "{:+.1f} points"))),
}


def claim_d_section(results: dict, claim: ClaimD) -> list[str]:
    """Claim (d): the PCHC policy (first checkpoint) at each fixed-preference policy's preference, beside it; the
    verdict is Pareto dominance on the task's two front objectives."""
    pchc, *fixed = results["results"]
    pchc_rows = rows_by_preference(pchc)
    pchc_steps = pchc.get("env_steps") or env_steps(pchc.get("checkpoint", ""))
    titles = [title for _, title, _ in claim.columns]
    names = "disturbance, stride" if claim.evaluation is WALK_EVALUATION else "energy, disturbance"
    lines = [f"| Policy | lambda ({names}) | Env steps | " + " | ".join(titles) + " | Episodes |",
             "|---|---|---|" + "---|" * len(titles) + "---|"]
    verdicts = []
    for result in fixed:
        (lam, row), = rows_by_preference(result).items()
        if lam not in pchc_rows:
            raise SystemExit(f"g1_report: {pchc['name']} was not evaluated at {result['name']}'s preference {lam}.")
        ours_row = pchc_rows[lam]
        for name, steps, r in ((pchc["name"] + " (PCHC)", pchc_steps, ours_row),
                               (result["name"] + " (fixed)",
                                result.get("env_steps") or env_steps(result.get("checkpoint", "")), row)):
            cells = " | ".join(cell(r, key, digits) for key, _, digits in claim.columns)
            lines.append(f"| {name} | {preference_label(lam)} | {'n/a' if steps is None else f'{steps:,}'} | "
                         f"{cells} | {r['episodes']} |")
        ours, theirs = front_points([ours_row, row], claim.evaluation)
        relation = ("the fixed policy dominates PCHC" if dominates(theirs, ours) else
                    "PCHC dominates the fixed policy" if dominates(ours, theirs) else "neither dominates")
        differences = ", ".join(f"{label} " + form.format(value(ours_row, key) - value(row, key))
                                for label, key, form in claim.differences)
        verdicts.append(f"- At {preference_label(lam)}: {differences} (PCHC minus fixed); {relation}.")
    return lines + [""] + verdicts


def targets_table(targets: list[tuple[str, bool, str]]) -> list[str]:
    lines = ["| Target | Status | Measured |", "|---|---|---|"]
    lines += [f"| {name} | {verdict(ok)} | {measured} |" for name, ok, measured in targets]
    return lines


def training_summary(spec: str, tags: list[str], out: str, checkpoint: str | None = None) -> list[str]:
    """Plot the run's curves into ``out`` and return a line with its env steps and wall-clock hours, and where on
    them the evaluated ``checkpoint`` was taken (the runs may have gone on past it)."""
    print(summary_table(plot_training([spec], tags, [os.path.basename(out).removesuffix(".png")], out)))
    steps, hours, _ = run_curves(spec, "Train/mean_reward")
    if len(steps) == 0:
        return [f"No training events under {spec}."]
    line = (f"Trained for {int(steps[-1]):,} env steps in {hours[-1]:.1f} wall-clock hours "
            f"(PPO iterations' collection + learning time).")
    taken = env_steps(checkpoint) if checkpoint else None
    if taken is not None and taken < steps[-1]:
        at = min(int(np.searchsorted(steps, taken)), len(steps) - 1)
        line += (f" The evaluated checkpoint was taken at {taken:,} env steps, after {hours[at]:.1f} hours; the "
                 "curves go on past it.")
    return [line]


def copy_plot(folder: str, name: str, docs: str, new_name: str) -> str | None:
    source = os.path.join(folder, name)
    if not os.path.exists(source):
        return None
    shutil.copyfile(source, os.path.join(docs, new_name))
    return new_name


def robustness_lines(folder: str, docs: str, stem: str) -> list[str]:
    """The deployment shifts of a pchc-eval --robustness folder: its heatmap (drawn again from robustness.json)
    and its tables."""
    from pchc_rsl.evaluation.robustness import plot_robustness, robustness_markdown

    with open(os.path.join(folder, "robustness.json")) as f:
        report = json.load(f)
    for row in report["rows"]:
        row["metrics"] = {k: (math.nan if v is None else v) for k, v in row["metrics"].items()}
    name = f"{stem}_robustness.png"
    plot_robustness(report, os.path.join(docs, name))
    episodes = sorted({row["episodes"] for row in report["rows"]})
    tables = robustness_markdown(report).split("\n", 2)[2].replace("### ", "### Under the shifts: ")
    steering = steering_targets(report) if report["task"].startswith("g1-walk") else []
    if steering:
        tables += "\n\n### Steering and standing targets\n\n" + "\n".join(targets_table(steering))
    return ["Each condition is a list of `KEY=VALUE` overrides on the mild push preset (any one is also a plain "
            "`pchc-eval CKPT KEY=VALUE ...`; `pchc-eval CKPT --robustness` prints them); "
            f"{' to '.join(str(e) for e in episodes[::max(1, len(episodes) - 1)])} episodes per cell. Rates with "
            "the Wilson 95% interval, other figures with the t interval.", "",
            f"![Deployment shifts]({name})", "", tables.strip(), ""]


def main(argv: list[str] | None = None) -> str | list[str]:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--walk", help="pchc-eval output folder of the walking policy (first checkpoint: PCHC)")
    parser.add_argument("--fall", help="pchc-eval output folder of the fall-recovery policy")
    parser.add_argument("--walk-robustness", help="pchc-eval --robustness output folder of the walking policy")
    parser.add_argument("--fall-robustness", help="pchc-eval --robustness output folder of the fall-recovery policy")
    parser.add_argument("--walk-runs", help="the walking run's folders joined by '+', for the training curves")
    parser.add_argument("--fall-runs",
                        help="the fall-recovery run's folders joined by '+' (folder@N: its iterations up to N)")
    parser.add_argument("--claim-d", help="pchc-eval output folder of a PCHC walker (first) and fixed-preference "
                        "walkers trained for as many env steps")
    parser.add_argument("--claim-d-fall", help="the same for a PCHC fall-recovery policy and fixed-preference ones")
    parser.add_argument("--docs", default="docs/results")
    parser.add_argument("--force", action="store_true",
                        help="replace a section made from more episodes per preference than the new results have")
    args = parser.parse_args(argv)
    inputs = {"walk": (args.walk, args.walk_robustness, args.claim_d),
              "fall": (args.fall, args.fall_robustness, args.claim_d_fall)}
    if not any(any(given) for given in inputs.values()):
        raise SystemExit("g1_report: give --walk, --fall, their --*-robustness, --claim-d and/or --claim-d-fall "
                         "(pchc-eval output folders).")
    os.makedirs(args.docs, exist_ok=True)
    sections = {"walk": ("Walking (Table II)", args.walk, walk_section, args.walk_runs, "g1_walk",
                         ["Train/mean_reward", "Episode_Termination/fall"]),
                "fall": ("Fall recovery from prone (Table I)", args.fall, fall_section, args.fall_runs, "g1_fall",
                         ["Train/mean_reward", "Metrics/success", "Curriculum/assist_level",
                          "Curriculum/action_scale"])}
    written = []
    for card, (evaluated, robust, claim_folder) in inputs.items():
        if not any((evaluated, robust, claim_folder)):
            continue
        file, title_line = CARDS[card]
        path = os.path.join(args.docs, file)
        previous = generated_sections(path)  # a section (or its training curves) whose inputs are not given is kept
        out = [kept_text(path, title_line), "", GENERATED_MARKER, ""]
        title, folder, section, runs, stem, tags = sections[card]
        if not folder:
            if title in previous:
                out += [f"## {title}", "", previous[title], ""]
        else:
            results = load_results(folder)
            episodes = min(row.get("episodes", 0) for row in results["results"][0]["rows"])
            before = episodes_of(previous.get(title, ""))
            if before is not None and episodes < before and not args.force:
                raise SystemExit(f"g1_report: {path}'s '{title}' was made from {before} episodes per preference, "
                                 f"{folder} has {episodes}; pass --force to replace it, or --docs a new folder.")
            table, targets = section(results)
            out += [f"## {title}", "", EPISODES_NOTE.format(episodes),
                    f"Evaluated with `pchc-eval` (seed {results['seed']}): no randomisation, no observation noise, "
                    "the paper's pushes (docs/evaluation.md). Our figure is the mean with its 95% interval (t for "
                    "measured quantities, Wilson for rates); the paper's is its table's.", "",
                    *table, "", "### Targets", "", GROWS, "", *targets_table(targets), ""]
            for plot, caption in (("pareto.png", "Pareto front"), ("switching.png", "Switching lambda mid-episode"),
                                  ("energy_curve.png", "Energy per step")):
                name = copy_plot(folder, plot, args.docs, f"{stem}_{plot}")
                if name:
                    out += [f"![{caption}]({name})", ""]
            if runs:
                curves = f"{stem}_training.png"
                out += ["### Training", "", *training_summary(runs, tags, os.path.join(args.docs, curves),
                                                           results["results"][0].get("checkpoint")), "",
                        f"![Training curves]({curves})", ""]
            elif subsection(previous.get(title, ""), "Training"):
                out += [subsection(previous[title], "Training"), ""]
        shifts = "Deployment shifts"
        if robust:
            out += [f"## {shifts}", "", *robustness_lines(robust, args.docs, stem)]
        elif shifts in previous:
            out += [f"## {shifts}", "", previous[shifts], ""]
        claim = CLAIM_D[card]
        if claim_folder:
            results = load_results(claim_folder)
            out += [f"## {claim.title}", "",
                    "The paper (Sec. V, 'Compared with fixed preference'): PCHC performs comparably to policies "
                    f"trained at one fixed lambda. Each fixed-preference {claim.policy} is evaluated at its own "
                    f"preference; the PCHC {claim.policy} at every preference (seed {results['seed']}, same "
                    "evaluation as above).", "", *claim_d_section(results, claim), ""]
            name = copy_plot(claim_folder, "pareto.png", args.docs, claim.plot)
            if name:
                out += [f"![PCHC and fixed-preference {claim.policies}]({name})", ""]
        elif claim.title in previous:
            out += [f"## {claim.title}", "", previous[claim.title], ""]
        with open(path, "w") as f:
            f.write("\n".join(out).rstrip() + "\n")
        print(f"g1_report: wrote {path}")
        written.append(path)
    return written[0] if len(written) == 1 else written


if __name__ == "__main__":
    main()
