"""Pareto-front metrics (maximisation throughout): non-dominated filter, hypervolume, sparsity."""

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
