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


MAX_PAIRS = 10_000
"""pairs_for_power's search bound: a difference that needs more is reported as too small to settle."""


def paired_log_ratio(numerator: list[float], denominator: list[float]) -> dict:
    """Mean over pairs of log(numerator / denominator) with its 95% Student-t interval, and the ratio exp() of each.

    The log makes the comparison scale-free (a ratio, as the paper reports) and symmetric; the pairing removes what a
    seed does to both variants. Fewer than two pairs: no interval (NaN).
    """
    from scipy import stats

    d = np.log(np.asarray(numerator, dtype=float)) - np.log(np.asarray(denominator, dtype=float))
    n = len(d)
    mean = float(d.mean()) if n else float("nan")
    sd = float(d.std(ddof=1)) if n >= 2 else float("nan")
    half = float(stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n)) if n >= 2 else float("nan")
    low, high = mean - half, mean + half
    effect = abs(mean) / sd if sd > 0 else (math.inf if mean else 0.0)  # pairs that all agree: no spread
    return {"n": n, "mean_log_ratio": mean, "ci95": [low, high], "ratio": math.exp(mean) if n else float("nan"),
            "ratio_ci95": [math.exp(low), math.exp(high)], "log_ratios": d.tolist(), "sd_log_ratio": sd,
            "pairs_for_80pct_power": pairs_for_power(effect) if n >= 2 else None}


def pairs_for_power(effect: float, power: float = 0.8, alpha: float = 0.05) -> int | None:
    """The fewest pairs at which a two-sided paired t-test at level ``alpha`` finds a true mean log-ratio of
    ``effect`` standard deviations of the pair differences with probability ``power`` (the noncentral t; None beyond
    MAX_PAIRS). With the measured mean and spread as the truth, this is the study size a decisive answer needs."""
    from scipy import stats

    if math.isnan(effect) or effect <= 0:
        return None
    if math.isinf(effect):  # two pairs that agree exactly show it
        return 2
    for n in range(2, MAX_PAIRS + 1):
        critical = stats.t.ppf(1 - alpha / 2, n - 1)
        shift = effect * math.sqrt(n)
        achieved = stats.nct.sf(critical, n - 1, shift) + stats.nct.cdf(-critical, n - 1, shift)
        if achieved >= power:
            return n
    return None
