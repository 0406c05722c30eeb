"""The evaluation's figures: the Pareto front, fall recovery's energy curves, the preference switch."""

from __future__ import annotations

import math

import numpy as np


def figure(figsize: tuple[float, float], nrows: int = 1, ncols: int = 1, **subplots):
    """(figure, axes) drawn off screen to be saved: matplotlib's Figure without pyplot, so no window opens, nothing
    is left open to close, and no backend is chosen for the process that imports this (a notebook keeps its own)."""
    from matplotlib.figure import Figure  # a third of a second, which every command importing the evaluation would pay

    fig = Figure(figsize=figsize)
    return fig, fig.subplots(nrows, ncols, **subplots)


HV_S_NOTE = ("HV (hypervolume): the area between the front and the reference point; larger is better.\n"
             "S (sparsity): the mean squared gap between neighbouring front points; smaller is more even.")


def plot_pareto(results, evaluation, path):
    """Each policy's points (one per preference) in the signed front coordinates, HV and S in the legend, the
    paper's points where it gives them in the same units, and what HV and S mean under the axes."""
    (a, sign_a), (b, sign_b) = evaluation.front  # plotted signed, as the front and its reference point are
    fig, ax = figure((5.5, 5.0))
    for result in results:
        xs = [sign_a * r["metrics"].get(a, np.nan) for r in result["rows"]]
        ys = [sign_b * r["metrics"].get(b, np.nan) for r in result["rows"]]
        f = result["front"]
        ax.plot(xs, ys, "o-", label=f"{result['name']}: HV {f['hypervolume']:.3g}, S {f['sparsity']:.3g}")
        for row, x, y in zip(result["rows"], xs, ys):
            ax.annotate("(" + ", ".join(f"{v:.2f}" for v in row["preference"]) + ")", (x, y), fontsize=7)
    if evaluation.paper_front:
        points = sorted(evaluation.paper_front.items(), reverse=True)
        ax.plot([sign_a * p[0] for _, p in points], [sign_b * p[1] for _, p in points], "x--", color="0.4",
                label=f"paper, {evaluation.table}")
    note = HV_S_NOTE + (f"\n{evaluation.paper_note}" if evaluation.paper_note else "")
    ax.set_xlabel(("−" if sign_a < 0 else "") + evaluation.columns.get(a, a) + " (more is better)")
    ax.set_ylabel(("−" if sign_b < 0 else "") + evaluation.columns.get(b, b) + " (more is better)")
    ax.set_title(f"{evaluation.table}; HV reference point {evaluation.reference_point}", fontsize=9)
    empty = _empty_front_reason(results, evaluation)
    if empty:
        ax.text(0.5, 0.5, empty, transform=ax.transAxes, ha="center", va="center", fontsize=8, wrap=True)
    ax.legend(fontsize=7)
    fig.text(0.01, 0.01, note, fontsize=6.5, va="bottom", ha="left")
    fig.tight_layout(rect=(0, 0.09 if evaluation.paper_note else 0.07, 1, 1))
    fig.savefig(path, dpi=120)
    return path


def _empty_front_reason(results, evaluation) -> str:
    """Why there is no point to plot, or '' when there is one: the front metric(s) undefined at every preference."""
    keys = [key for key, _ in evaluation.front]
    rows = [row for result in results for row in result["rows"]]
    if any(all(math.isfinite(row["metrics"].get(key, math.nan)) for key in keys) for row in rows):
        return ""
    undefined = [key for key in keys if not any(math.isfinite(r["metrics"].get(key, math.nan)) for r in rows)]
    return (f"No point to plot: {' and '.join(undefined)} undefined at every preference.\n"
            "No episode lasted long enough to measure it\n(e.g. every episode fell before the first push).")


def plot_energy_curves(curves, path):
    fig, ax = figure((5.5, 3.5))
    for name, by_preference in curves.items():
        for lam, curve in sorted(by_preference.items()):
            ax.plot(-curve[:, 1], label=f"{name} {lam}")
    ax.set_xlabel("policy step")
    ax.set_ylabel("-r_energy per step")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return path


def plot_switching(switch, path):
    fig, ax = figure((5.5, 3.5))
    t = np.arange(len(switch["curve"])) * switch["dt"]
    for i, name in enumerate(switch["objectives"]):
        ax.plot(t, switch["curve"][:, i], label=f"r_{name}")
    ax.axvline(switch["switch_step"] * switch["dt"], color="k", ls="--", label="lambda (0,1) -> (1,0)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("objective reward per step (mean over envs)")
    settle = switch["settle_time_s"]
    settle = "n/a (no continuous objective)" if settle != settle else f"{settle:.2f} s"
    ax.set_title(f"falls {switch['falls']}, settle time {settle}", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return path

