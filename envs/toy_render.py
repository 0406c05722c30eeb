"""Pictures of the toy task (no MuJoCo scene): a 2-D plot of each env's trajectory towards its goals."""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


class ToyPlot:
    """One matplotlib figure per env, redrawn every frame: goals A and B, the Pareto segment, the path so far."""

    def __init__(self, env, width: int, height: int) -> None:
        self.env = env
        self.paths: list[list[np.ndarray]] = [[] for _ in range(env.num_envs)]
        self.figure = Figure(figsize=(width / 100, height / 100), dpi=100)
        self.canvas = FigureCanvasAgg(self.figure)
        self.axes = self.figure.add_axes((0.02, 0.02, 0.96, 0.96))

    def record(self) -> None:
        """Add the current positions to the paths (call after every step); a reset starts a new path."""
        for i, path in enumerate(self.paths):
            if self.env.episode_length_buf[i] == 0:
                path.clear()
            path.append(self.env.pos[i].numpy().copy())

    def render(self, env, i: int) -> np.ndarray:
        ax = self.axes
        ax.clear()
        goals = env.goals.numpy()
        ax.plot(goals[:, 0], goals[:, 1], "--", color="0.6", lw=1)  # the Pareto front: lambda_1 A + lambda_2 B
        ax.scatter(goals[:, 0], goals[:, 1], marker="*", s=120, color=["tab:blue", "tab:orange"])
        for goal, name in zip(goals, "AB"):
            ax.annotate(name, goal, textcoords="offset points", xytext=(6, -12))
        lam = env.preference[i].numpy()
        ax.scatter(*(lam @ goals), marker="x", color="tab:green")  # where the preference says to go
        path = np.array(self.paths[i] or [env.pos[i].numpy()])
        ax.plot(path[:, 0], path[:, 1], "-", color="tab:red", lw=1.5)
        ax.scatter(*path[-1], color="tab:red", zorder=3)
        ax.set_xlim(-0.4, 1.4)
        ax.set_ylim(-0.4, 1.7)  # room for the label at the top
        ax.set_xticks([])
        ax.set_yticks([])
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba())[..., :3].copy()

    def close(self) -> None:
        pass
