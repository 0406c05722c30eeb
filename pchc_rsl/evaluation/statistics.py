"""Per-episode metrics into means with 95% intervals: Student's t for measured quantities, Wilson for rates."""

from __future__ import annotations

import math

import numpy as np


RATE_METRICS = {"success": "success", "fell": "fall_rate"}
"""Per-episode 0/1 outcomes reported as percentages (metric key -> reported key)."""


DISTRIBUTION_METRICS = ("heading_drift", "lateral_drift")
"""Metrics whose spread over episodes matters as much as their mean: also reported as KEY_median and KEY_p90."""

Z95 = 1.959963984540054


def aggregate(episodes: list[dict[str, float]]) -> dict:
    """Mean of each metric over episodes, ignoring NaN (a metric undefined in an episode, e.g. no push), with its
    95% interval under ``KEY_ci95`` ([low, high]): Student's t for measured quantities, Wilson's score interval for
    the 0/1 outcomes 'success' and 'fell', which become percentages ('fell' is reported as 'fall_rate'); the
    DISTRIBUTION_METRICS also with their median and 90th percentile."""
    keys = sorted({k for e in episodes for k in e})
    out: dict = {}
    for key in keys:
        values = np.array([e[key] for e in episodes if key in e], dtype=float)
        values = values[~np.isnan(values)]
        n = len(values)
        mean = float(values.mean()) if n else float("nan")
        if key in RATE_METRICS:
            interval = [100.0 * x for x in wilson_interval(mean, n)]
            key, mean = RATE_METRICS[key], 100.0 * mean
        elif n >= 2:
            from scipy import stats  # half a second, which every command importing the evaluation would pay at start

            half = float(stats.t.ppf(0.975, n - 1) * values.std(ddof=1) / math.sqrt(n))
            interval = [mean - half, mean + half]
        else:
            interval = [float("nan"), float("nan")]
        out[key] = mean
        out[f"{key}_ci95"] = interval
        if key in DISTRIBUTION_METRICS:
            out[f"{key}_median"] = float(np.median(values)) if n else float("nan")
            out[f"{key}_p90"] = float(np.percentile(values, 90)) if n else float("nan")
    return out


def wilson_interval(p: float, n: int) -> tuple[float, float]:
    """95% Wilson score interval of a proportion p observed in n trials (stays inside [0, 1], also at 0 or 1)."""
    if n == 0 or p != p:
        return float("nan"), float("nan")
    z2 = Z95 * Z95
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = Z95 * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    return centre - half, centre + half

