"""Deployment shifts: every preference under the conditions a robot brings (latency, other physics, friction,
payload, weaker motors, sensor noise, other commands, stronger pushes), each a list of ``KEY=VALUE`` overrides on
top of the task's evaluation preset, so any one of them is also a plain ``pchc-eval CKPT KEY=VALUE ...``.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field

import numpy as np

from pchc_rsl.evaluation.checkpoint import evaluate_checkpoint
from pchc_rsl.evaluation.plots import figure
from pchc_rsl.evaluation.presets import FALL_RECOVERY_EVALUATION, TASK_EVALUATION, WALK_EVALUATION
from pchc_rsl.evaluation.report import _finite_or_null, format_metric
from pchc_rsl.utils.files import recorded_path


@dataclass
class Condition:
    name: str
    overrides: list[str] = field(default_factory=list)


def _physical(friction: float = 1.0, mass: float = 0.0, strength: float = 1.0) -> list[str]:
    """One model variant with exactly these physical values (randomisation's machinery, ranges of one value)."""
    return ["env.randomization.enabled=true", "env.randomization.num_model_variants=1",
            f"env.randomization.friction={friction},{friction}", f"env.randomization.added_base_mass={mass},{mass}",
            f"env.randomization.actuator_strength={strength},{strength}"]


def _command(speed: float, lateral: float = 0.0, yaw_rate: float = 0.0) -> list[str]:
    ranges = {"lin_vel_x": [speed, speed], "lin_vel_y": [lateral, lateral], "ang_vel_z": [yaw_rate, yaw_rate]}
    return ["env.command_ranges=" + json.dumps(ranges).replace(" ", "")]  # the preset already drops standing episodes


STEERING = [("turn left 0.5 rad/s", 0.5, 0.0, 0.5), ("turn right 0.5 rad/s", 0.5, 0.0, -0.5),
            ("side step left 0.3 m/s", 0.0, 0.3, 0.0), ("side step right 0.3 m/s", 0.0, -0.3, 0.0)]
"""Steering commands of the walking evaluation: (name, forward m/s, lateral m/s, yaw rate rad/s); their yaw-rate
and lateral-speed errors say whether the walker goes where it is told."""


def _force_push(preset) -> list[str]:
    """A PushPreset's force, in place of the evaluation preset's kicks (same interval and window)."""
    low, high = preset.force
    bodies = json.dumps({b: 1.0 for b in preset.bodies}).replace(" ", "")
    return ["env.push.velocity_share=0", "env.push.force.share=1", f"env.push.force.magnitude={low},{high}",
            f"env.push.force.duration_s={preset.duration_s},{preset.duration_s}", f"env.push.force.bodies={bodies}"]


WALK_FORCE_PRESETS = ("force-mild", "force-strong", "force-legs")
FALL_RECOVERY_FORCE_PRESETS = ("force-mild", "force-strong")
"""The task's force presets each a condition of their own (pushes as a robot meets them)."""

WALK_PUSH_SWEEP = (1.0, 1.5, 2.0)
FALL_RECOVERY_PUSH_SWEEP = (1.6, 2.0, 2.4)
"""Push speeds (m/s) of the sweep, beyond the presets."""


def default_conditions(task: str) -> list[Condition]:
    """The default set of deployment shifts: nominal, action latency 10 and 20 ms, the paper physics for a
    ``-fast`` policy, friction 0.4 and 1.2, pelvis mass -1 and +5 kg, actuator strength 0.8, observation noise,
    commands 0 and 1.0 m/s and the steering commands (walking; 0.5 m/s straight is the nominal), a push-speed
    sweep, and the task's force presets."""
    walking = task.startswith("g1-walk")
    conditions = [
        Condition("nominal"),
        Condition("latency 10 ms", ["env.action_delay_s=0.01,0.01"]),
        Condition("latency 20 ms", ["env.action_delay_s=0.02,0.02"]),
    ]
    if task.endswith("-fast"):
        conditions.append(Condition("paper physics (2 ms, x10)", ["env.timestep=0.002", "env.decimation=10"]))
    conditions += [
        Condition("friction 0.4", _physical(friction=0.4)),
        Condition("friction 1.2", _physical(friction=1.2)),
        Condition("pelvis -1 kg", _physical(mass=-1.0)),
        Condition("pelvis +5 kg", _physical(mass=5.0)),
        Condition("actuators x0.8", _physical(strength=0.8)),
        Condition("observation noise", ["env.observation_noise=1.0"]),
    ]
    if walking:
        conditions += [Condition("command 0 m/s", _command(0.0)), Condition("command 1.0 m/s", _command(1.0))]
        conditions += [Condition(name, _command(*command)) for name, *command in STEERING]
    for speed in WALK_PUSH_SWEEP if walking else FALL_RECOVERY_PUSH_SWEEP:
        conditions.append(Condition(f"push {speed:g} m/s", [f"env.push.velocity={speed},{speed}"]))
    evaluation = WALK_EVALUATION if walking else FALL_RECOVERY_EVALUATION
    for name in WALK_FORCE_PRESETS if walking else FALL_RECOVERY_FORCE_PRESETS:
        preset = evaluation.pushes[name]
        where = "legs" if "legs" in name else "torso/pelvis"
        conditions.append(Condition(f"force {preset.force[0]:g}-{preset.force[1]:g} N {where}", _force_push(preset)))
    return conditions


HEADLINE = {
    "walk": [("fall_rate", "falls (%)"), ("forward_speed", "forward speed (m/s)"),
             ("yaw_rate_error", "yaw-rate error (rad/s)"), ("lateral_speed_error", "lateral-speed error (m/s)")],
    "fall": [("success", "success (%)"), ("energy_overall", "energy (J/s)")],
}
"""The figures robustness.md and the heatmap show per task family (robustness.json has every metric)."""


def headline(task: str, rows: list[dict] | None = None) -> list[tuple[str, str]]:
    """The task's headline figures; with ``rows``, only those that some row has."""
    figures = HEADLINE["walk" if task.startswith("g1-walk") else "fall"]
    if rows is None:
        return figures
    return [(key, title) for key, title in figures if any(key in row["metrics"] for row in rows)]


def run_robustness(path: str, config: dict, preferences, conditions: list[Condition], num_envs: int, episodes: int,
                   seed: int, overrides: list[str] = (), verbose: bool = False, device: str = "cpu",
                   on_condition=None) -> dict:
    """Each condition's metrics at every preference, under the task's first push preset (mild) with the
    condition's overrides after the user's. Returns {"task", "conditions", "rows"}; ``on_condition(report)`` is
    called after each condition with the report of the conditions finished so far (marked ``"partial": true``
    until the last), so that an interrupted run leaves them written."""
    evaluation = TASK_EVALUATION[config["task"]]
    presets = evaluation.push_presets[:1] or None
    rows, done = [], []

    def report(partial: bool) -> dict:
        return {"task": config["task"], "checkpoint": recorded_path(path),
                "objectives": list(config["env"]["objective_names"]),
                "conditions": [c.name for c in done], "rows": list(rows), "partial": partial}

    for condition in conditions:
        print(f"robustness: {condition.name} ({' '.join(condition.overrides) or 'the evaluation preset'})",
              flush=True)
        result, _, _ = evaluate_checkpoint(path, config, preferences, num_envs=num_envs, episodes=episodes,
                                           seed=seed, overrides=[*overrides, *condition.overrides],
                                           verbose=verbose, device=device, presets=presets)
        for row in result["rows"]:
            rows.append({"condition": condition.name, "overrides": condition.overrides,
                         "preference": row["preference"], "episodes": row["episodes"], "metrics": row["metrics"]})
        done.append(condition)
        if on_condition is not None and len(done) < len(conditions):
            on_condition(report(partial=True))
    return report(partial=False)


def robustness_markdown(report: dict) -> str:
    """One table per headline figure: a row per condition, a column per preference."""
    preferences = []
    for row in report["rows"]:
        if row["preference"] not in preferences:
            preferences.append(row["preference"])
    cell = {(r["condition"], tuple(r["preference"])): r for r in report["rows"]}
    lines = [f"Deployment shifts of {report['checkpoint']} ({report['task']}); mean ± 95% interval half-width, "
             "rates with the Wilson 95% interval", ""]
    if report.get("partial"):
        lines[1:1] = ["", f"**Partial**: interrupted after {len(report['conditions'])} condition(s); the others did "
                      "not run."]
    for key, title in headline(report["task"], report["rows"]):
        lines += [f"### {title}", "",
                  f"| Condition \\ lambda ({', '.join(report.get('objectives') or ['obj 1', 'obj 2'])}) | "
                  + " | ".join("(" + ", ".join(f"{x:.2f}" for x in p) + ")" for p in preferences)
                  + " |", "|---|" + "---|" * len(preferences)]
        for condition in report["conditions"]:
            cells = []
            for p in preferences:
                metrics = cell[(condition, tuple(p))]["metrics"] if (condition, tuple(p)) in cell else {}
                value = metrics.get(key)
                cells.append(format_metric(np.nan if value is None else value, metrics.get(f"{key}_ci95"), key))
            lines.append(f"| {condition} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


COLOUR_RANGE_FLOOR = {"forward_speed": 1.0, "energy_overall": 400.0}
"""The least top of a continuous metric's colour scale (m/s, J/s): the scale starts at 0, so that 0.48 and
0.62 m/s sit close together as they are, not at the two ends of a scale stretched between them."""


def colour_range(key: str, values: np.ndarray) -> tuple[float, float]:
    """(vmin, vmax) of a headline metric's colour scale: 0-100 for rates, else 0 to the larger of the highest value
    and the metric's floor."""
    if key in ("fall_rate", "success"):
        return 0.0, 100.0
    finite = values[np.isfinite(values)]
    top = float(finite.max()) if finite.size else 1.0
    return 0.0, max(top, COLOUR_RANGE_FLOOR.get(key, 0.0)) or 1.0


def cell_text(key: str, value: float) -> str:
    """A heatmap cell's figure: rates in % to one decimal (100 as 100), other figures to three significant digits."""
    if key in ("fall_rate", "success"):
        return "100" if value >= 99.95 else f"{value:.1f}"
    return f"{value:.0f}" if abs(value) >= 100 else f"{value:.3g}"


def plot_robustness(report: dict, path: str) -> str:
    """Heatmap(s) preference x condition of the headline figures, under a title naming the policy, each with its
    own colour scale from 0 (rates 0-100%)."""
    figures = headline(report["task"], report["rows"])
    conditions = report["conditions"]
    preferences = []
    for row in report["rows"]:
        if row["preference"] not in preferences:
            preferences.append(row["preference"])
    cell = {(r["condition"], tuple(r["preference"])): r["metrics"] for r in report["rows"]}
    fig, axes = figure((3.2 + 2.2 * len(figures), 0.35 * len(conditions) + 1.6), 1, len(figures), squeeze=False)
    for ax, (key, title) in zip(axes[0], figures):
        values = np.array([[cell.get((c, tuple(p)), {}).get(key) for p in preferences] for c in conditions],
                          dtype=float)
        vmin, vmax = colour_range(key, values)
        image = ax.imshow(values, aspect="auto", cmap="viridis_r" if key == "fall_rate" else "viridis",
                          vmin=vmin, vmax=vmax)
        ax.set_xticks(range(len(preferences)), ["(" + ", ".join(f"{x:.2g}" for x in p) + ")" for p in preferences],
                      fontsize=7, rotation=30)
        ax.set_yticks(range(len(conditions)), conditions if ax is axes[0][0] else [""] * len(conditions), fontsize=7)
        for i in range(len(conditions)):
            for j in range(len(preferences)):
                if np.isfinite(values[i, j]):
                    r, g, b, _ = image.cmap(image.norm(values[i, j]))
                    ink = "k" if 0.299 * r + 0.587 * g + 0.114 * b > 0.5 else "w"
                    ax.text(j, i, cell_text(key, values[i, j]), ha="center", va="center", fontsize=6, color=ink)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("lambda (" + ", ".join(report.get("objectives") or ["obj 1", "obj 2"]) + ")", fontsize=7)
        fig.colorbar(image, ax=ax, shrink=0.8)
    episodes = sorted({r["episodes"] for r in report["rows"]})
    fig.suptitle(f"{os.path.basename(report['checkpoint'])} ({report['task']}) under deployment shifts\nmild "
                 f"pushes, {'-'.join(str(e) for e in episodes[::max(1, len(episodes) - 1)])} episodes per cell",
                 fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def write_robustness(report: dict, output: str) -> list[str]:
    os.makedirs(output, exist_ok=True)
    paths = [os.path.join(output, name) for name in ("robustness.json", "robustness.md", "robustness.png")]
    with open(paths[0], "w") as f:
        json.dump(_finite_or_null(report), f, indent=2, allow_nan=False)
    with open(paths[1], "w") as f:
        f.write(robustness_markdown(report))
    plot_robustness(report, paths[2])
    return paths
