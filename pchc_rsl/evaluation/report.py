"""Pareto summaries, the paper's tables and the files pchc-eval writes (results.json, table.md, the plots)."""

from __future__ import annotations

import json
import math
import os

import numpy as np

from pchc_rsl.evaluation.plots import plot_energy_curves, plot_pareto, plot_switching
from pchc_rsl.evaluation.presets import TaskEvaluation
from pchc_rsl.pareto import hypervolume, non_dominated, sparsity


def front_points(rows: list[dict], evaluation: TaskEvaluation) -> np.ndarray:
    """[n, 2] signed objective metrics (more is better) of the evaluated preferences."""
    (a, sa), (b, sb) = evaluation.front
    return np.array([[sa * r["metrics"][a], sb * r["metrics"][b]] for r in rows])


def front_summary(points: np.ndarray, evaluation: TaskEvaluation) -> dict:
    """Hypervolume (with its reference point) and sparsity of the non-dominated subset of ``points``."""
    finite = points[np.isfinite(points).all(axis=1)]
    if len(finite) == 0:
        return {"hypervolume": 0.0, "sparsity": float("nan"), "reference_point": list(evaluation.reference_point),
                "num_points": 0}
    front = non_dominated(finite)
    return {
        "hypervolume": hypervolume(front, evaluation.reference_point),
        "sparsity": sparsity(front),
        "reference_point": list(evaluation.reference_point),
        "num_points": int(len(front)),
    }


def markdown_table(results: list[dict], evaluation: TaskEvaluation) -> str:
    """The paper's table: one row per (checkpoint, preference), each figure with its 95% interval."""
    preference = f"lambda ({', '.join(evaluation.objectives)})" if evaluation.objectives else "Preference"
    header = ["Policy", preference, *evaluation.columns.values(), "Episodes"]
    lines = [f"{evaluation.table}; mean ± 95% interval half-width (t), rates with the Wilson 95% interval", "",
             "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for result in results:
        for row in result["rows"]:
            lam = "(" + ", ".join(f"{x:.2f}" for x in row["preference"]) + ")"
            metrics = row["metrics"]
            cells = [format_metric(metrics.get(key, math.nan), metrics.get(f"{key}_ci95"), key)
                     for key in evaluation.columns]
            lines.append("| " + " | ".join([result["name"], lam, *cells, str(row.get("episodes", ""))]) + " |")
    return "\n".join(lines) + "\n"


def format_metric(value: float, interval: list[float] | None = None, key: str = "", digits: int = 2) -> str:
    """'mean ± half-width', or 'rate [low, high]' for rates (their intervals are not symmetric); 'n/a' where
    undefined, the bare mean where the interval is (missing, or NaN / None as results.json stores it)."""
    if value != value:
        return "n/a"
    if not interval or interval[0] is None or interval[0] != interval[0]:
        return f"{value:.{digits}f}"
    if key.endswith(("success", "fall_rate")):
        return f"{value:.1f} [{interval[0]:.1f}, {interval[1]:.1f}]"
    return f"{value:.{digits}f} ± {(interval[1] - interval[0]) / 2:.{digits}f}"


def write_outputs(results, evaluation, curves, switching, output: str, seed: int, overrides: list[str] = ()
                  ) -> list[str]:
    """results.json (strict JSON: null where a metric is undefined), table.md and the plots; the paths written."""
    os.makedirs(output, exist_ok=True)
    path = os.path.join(output, "results.json")
    with open(path, "w") as f:
        json.dump(_finite_or_null({"table": evaluation.table, "seed": seed, "overrides": list(overrides),
                                   "results": results,
                                   "switching": _switching_json(switching)}), f, indent=2, allow_nan=False)
    written = [path]
    path = os.path.join(output, "table.md")
    with open(path, "w") as f:
        f.write(markdown_table(results, evaluation))
    written.append(path)
    written.append(plot_pareto(results, evaluation, os.path.join(output, "pareto.png")))
    if "energy_overall" in evaluation.columns:
        written.append(plot_energy_curves(curves, os.path.join(output, "energy_curve.png")))
    if switching is not None:
        written.append(plot_switching(switching, os.path.join(output, "switching.png")))
    return written


def _finite_or_null(value):
    """A copy of nested dicts/lists with NaN and inf as None (JSON has no NaN) and numpy scalars as floats."""
    if isinstance(value, dict):
        return {k: _finite_or_null(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_null(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def _switching_json(switch):
    if switch is None:
        return None
    return {"falls": switch["falls"], "settle_time_s": switch["settle_time_s"], "objectives": switch["objectives"],
            "switch_time_s": switch["switch_step"] * switch["dt"], "objective_curves": switch["curve"].tolist()}

