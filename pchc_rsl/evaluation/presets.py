"""What each task measures and the evaluation preset it runs under (no randomisation, no noise, fixed pushes
and command)."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field


@dataclass
class TaskEvaluation:
    """What to measure for one task family."""

    table: str
    columns: dict[str, str]
    """metric key -> column title of the paper's table."""
    front: tuple[tuple[str, float], tuple[str, float]]
    """The two objective metrics of the Pareto plot, each with the sign that makes it 'more is better'."""
    reference_point: tuple[float, float]
    """Hypervolume reference point in the signed front coordinates (stated with every figure)."""
    episode_returns: bool = False
    """Measure each objective's undiscounted episode return (run_return_episodes) instead of the env's
    episode_metrics, with the task's config as it is (no evaluation preset): for envs without task metrics."""
    push_presets: list[str] = field(default_factory=lambda: ["mild"])
    command: tuple[float, float, float] | None = None
    push_only_when_standing: bool = False
    """Push the robot once it stands (fall recovery), not while it is still on the floor."""


WALK_EVALUATION = TaskEvaluation(
    table="Table II (walking)",
    columns={"stride_length": "Avg. Stride (m)", "push_deviation": "Traj. Deviation (m)", "fall_rate": "Falls (%)",
             "forward_step": "Forward step (m)", "side_step": "Side step (m)", "cadence": "Cadence (1/s per foot)",
             "air_time": "Air time, median (s)", "backward_touchdowns": "Backward touchdowns (%)",
             "forward_speed": "Forward speed (m/s)"},
    front=(("push_deviation", -1.0), ("stride_length", 1.0)),
    reference_point=(-2.0, 0.0),
    push_presets=["mild"],
    command=(0.5, 0.0, 0.0),
)


FALL_RECOVERY_EVALUATION = TaskEvaluation(
    table="Table I (fall recovery)",
    columns={
        "energy_overall": "Avg. Energy Overall (J/s)",
        "energy_recovery": "Avg. Energy Fall Recovery (J/s)",
        "energy_standing": "Avg. Energy Recovery (J/s)",
        "torque_overall": "Avg. Torque Overall (Nm)",
        "torque_recovery": "Avg. Torque Fall Recovery (Nm)",
        "torque_standing": "Avg. Torque Recovery (Nm)",
        "mild/com_displacement": "COM displacement (m)",
        "mild/success": "Success, mild pushes (%)",
        "strong/success": "Success, strong pushes (%)",
    },
    front=(("energy_overall", -1.0), ("mild/com_displacement", -1.0)),
    reference_point=(-3000.0, -3.0),
    push_presets=["mild", "strong"],
    push_only_when_standing=True,
)


TOY_EVALUATION = TaskEvaluation(
    table="Toy task (two goals)",
    columns={"goal_a": "Return goal A (undiscounted)", "goal_b": "Return goal B (undiscounted)"},
    front=(("goal_a", 1.0), ("goal_b", 1.0)),
    reference_point=(-60.0, -60.0),
    push_presets=[],
    episode_returns=True,
)


TASK_EVALUATION = {
    "toy": TOY_EVALUATION,
    "g1-walk": WALK_EVALUATION,
    "g1-walk-fast": WALK_EVALUATION,
    "g1-fall-recovery": FALL_RECOVERY_EVALUATION,
    "g1-fall-recovery-fast": FALL_RECOVERY_EVALUATION,
}


def evenly_spaced_preferences(count: int) -> list[tuple[float, float]]:
    """(1, 0), ..., (0, 1) in ``count`` steps."""
    if count < 2:
        raise ValueError(f"Need at least 2 preferences, got {count}.")
    return [(1 - i / (count - 1), i / (count - 1)) for i in range(count)]


def evaluation_preset(cfg, push_preset: str, evaluation: TaskEvaluation):
    """A copy of a task config for evaluation: no randomisation, no noise, no curriculum, the preset's pushes."""
    from pchc_rsl.envs.g1_env import PUSH_PRESETS

    cfg = copy.deepcopy(cfg)
    env = cfg.env
    env.randomization.enabled = False
    env.observation_noise = 0.0
    env.preference_resample_prob = 0.0
    env.push = copy.deepcopy(PUSH_PRESETS[push_preset])
    env.push.only_when_standing = evaluation.push_only_when_standing
    if hasattr(env, "curriculum"):
        env.curriculum = False
    if evaluation.command is not None:
        vx, vy, wz = evaluation.command
        env.command_ranges = {"lin_vel_x": (vx, vx), "lin_vel_y": (vy, vy), "ang_vel_z": (wz, wz)}
    return cfg

