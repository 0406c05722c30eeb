"""What is shown next to a robot while it runs (video tiles, the native and the web viewer): lambda, the objective's
running metric, the last push's deviation, falls or standing."""

from __future__ import annotations

import math

import torch


def _number(value: float, fmt: str) -> str:
    return "-" if value != value else format(value, fmt)


def live_metrics(env, i: int, falls: int) -> list[tuple[str, str]]:
    """(name, value) pairs shown next to a robot: stride or energy, the last push's deviation, falls or standing."""
    if not hasattr(env, "episode_metrics"):  # the toy: how far from each goal
        distance = (env.pos[i] - env.goals).norm(dim=-1)
        return [(f"distance to {n}", f"{d:.2f}") for n, d in zip("AB", distance.tolist())]
    metrics = {k: float(v[0]) for k, v in env.episode_metrics(torch.tensor([i])).items()}
    if "energy_overall" in metrics:
        rows = [("energy", _number(metrics["energy_overall"], ".0f") + " J/s")]
    else:
        rows = [("stride", _number(metrics.get("stride_length", math.nan), ".2f") + " m")]
    pushed = bool(env.pushes.active[i]) or not math.isnan(metrics.get("push_deviation", math.nan))
    deviation = float(env.pushes.max_deviation[i]) if pushed else math.nan
    rows.append(("push deviation", _number(deviation, ".2f") + " m"))
    if hasattr(env, "reached_standing"):
        rows.append(("state", "standing" if bool(env.reached_standing[i]) else "getting up"))
    else:
        rows.append(("falls", str(falls)))
    return rows


def preference_row(env, i: int) -> tuple[str, str]:
    """("lambda (obj_1, obj_2)", "(0.30, 0.70)")."""
    lam = ", ".join(f"{x:.2f}" for x in env.preference[i].tolist())
    return f"lambda ({', '.join(env.cfg.objective_names)})", f"({lam})"


def tile_label(env, i: int, falls: int) -> list[str]:
    name, value = preference_row(env, i)
    return [f"{name} = {value}"] + [f"{name}: {value}" for name, value in live_metrics(env, i, falls)]
