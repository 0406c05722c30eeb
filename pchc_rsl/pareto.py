"""Pareto-front metrics (maximisation throughout): non-dominated filter, hypervolume, sparsity, expected utility."""

from __future__ import annotations

import moocore
import numpy as np
from numpy.typing import ArrayLike


def _as_points(points: ArrayLike) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[0] == 0:
        raise ValueError(f"Expected a non-empty [n, m] array of objective values, got shape {p.shape}.")
    if not np.isfinite(p).all():
        raise ValueError("Objective values must be finite.")
    return p


def non_dominated(points: ArrayLike) -> np.ndarray:
    """The points no other point dominates, duplicates kept once, sorted lexicographically. [n, m] -> [k, m]."""
    p = _as_points(points)
    p = np.unique(p, axis=0)
    return p[moocore.is_nondominated(p, maximise=True)]


def hypervolume(points: ArrayLike, ref: ArrayLike) -> float:
    """Volume dominated by ``points`` and dominating ``ref`` (exact, via moocore).

    Points that do not strictly dominate ``ref`` in every objective add nothing. State ``ref`` with every figure:
    the value depends on it.
    """
    p = _as_points(points)
    r = np.asarray(ref, dtype=np.float64)
    if r.shape != (p.shape[1],):
        raise ValueError(f"The reference point must have {p.shape[1]} coordinates, got {r.shape}.")
    p = p[(p > r).all(axis=1)]
    if len(p) == 0:
        return 0.0
    return float(moocore.hypervolume(p, ref=r, maximise=True))


def sparsity(points: ArrayLike) -> float:
    """The paper's S(P) = 1/(n-1) sum_j sum_i (P_ij - P_(i+1)j)^2; lower is denser. 0 for fewer than 2 points.

    For each objective j the points are sorted along j before taking consecutive differences (as PGMORL does).
    With two objectives on a front this equals sorting the front once along an objective; with more than two
    there is no single order along a front, so each objective is sorted separately.
    """
    p = _as_points(points)
    n = len(p)
    if n < 2:
        return 0.0
    sorted_columns = np.sort(p, axis=0)
    return float(np.sum(np.diff(sorted_columns, axis=0) ** 2) / (n - 1))


def expected_utility(returns: ArrayLike, preferences: ArrayLike, low: ArrayLike, high: ArrayLike) -> float:
    """Mean over the preferences of lambda . normalised returns: how well the policy serves the preference it is given.

    returns [P, m] are the policy's returns at preferences [P, m]; each objective j is normalised as
    (R_j - low_j) / (high_j - low_j), with the task's fixed range (state it with every figure). Unlike the
    hypervolume, every preference counts, not only the non-dominated points, and no single end of the front dominates.
    """
    r = _as_points(returns)
    lam = np.asarray(preferences, dtype=np.float64)
    lo, hi = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
    if lam.shape != r.shape:
        raise ValueError(f"Need one preference per row of returns: returns {r.shape}, preferences {lam.shape}.")
    if lo.shape != (r.shape[1],) or hi.shape != (r.shape[1],) or not (hi > lo).all():
        raise ValueError(f"low and high must give each of the {r.shape[1]} objectives a range with high > low, "
                         f"got low {lo.tolist()}, high {hi.tolist()}.")
    return float(np.mean(np.sum(lam * (r - lo) / (hi - lo), axis=1)))
