"""What each task measures and the evaluation preset it runs under (no randomisation, no noise, fixed pushes
and command)."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

from pchc_rsl.envs.g1.config import ForcePushConfig, PushConfig

TORSO_AND_PELVIS = ("torso_link", "pelvis")
LEGS = ("left_knee_link", "right_knee_link", "left_ankle_roll_link", "right_ankle_roll_link")
"""The bodies of the force presets: where a hand or a door meets a robot, and where a kick or an obstacle does."""


@dataclass(frozen=True)
class PushPreset:
    """One evaluation push, every ``interval_s`` in a uniformly random horizontal direction: a velocity kick of
    ``speed`` m/s on the pelvis or, with ``force`` (N, a range), a force for ``duration_s`` on one of ``bodies``
    (equally likely). The after-disturb window lasts ``window_s`` from the push's onset."""

    window_s: float
    speed: float = 0.0
    force: tuple[float, float] | None = None
    duration_s: float = 0.08
    bodies: tuple[str, ...] = TORSO_AND_PELVIS
    interval_s: float = 3.0

    def push_config(self) -> PushConfig:
        """The env's push settings for this preset."""
        interval = (self.interval_s, self.interval_s)
        if self.force is None:
            return PushConfig(interval_s=interval, velocity=(self.speed, self.speed), window_s=self.window_s)
        force = ForcePushConfig(share=1.0, bodies={b: 1.0 for b in self.bodies}, magnitude=tuple(self.force),
                                duration_s=(self.duration_s, self.duration_s))
        return PushConfig(interval_s=interval, velocity_share=0.0, force=force, window_s=self.window_s)

    def describe(self, robot_mass: float) -> str:
        """What the push is, with its impulse and the speed it gives the whole robot (impulse / mass)."""
        if self.force is None:
            return f"kick {self.speed:g} m/s on the pelvis ({self.speed * robot_mass:.0f} N s)"
        low, high = self.force
        impulse = (low * self.duration_s, high * self.duration_s)
        speed = tuple(i / robot_mass for i in impulse)
        return (f"{low:g}-{high:g} N x {self.duration_s:g} s on {', '.join(self.bodies)}: {impulse[0]:.0f}-"
                f"{impulse[1]:.0f} N s, {speed[0]:.2f}-{speed[1]:.2f} m/s of the whole robot")


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
    """The push presets an evaluation runs, in order (the first one makes the unprefixed metrics)."""
    pushes: dict[str, PushPreset] = field(default_factory=dict)
    """Every push preset of the task by name."""
    command: tuple[float, float, float] | None = None
    push_only_when_standing: bool = False
    """Push the robot once it stands (fall recovery), not while it is still on the floor."""
    paper_front: dict[tuple[float, float], tuple[float, float]] = field(default_factory=dict)
    """The paper's figures of the two front metrics (unsigned, in ``front``'s order) by preference, drawn beside
    ours; empty where the paper gives none in the same units."""
    paper_note: str = ""
    """Why the paper's points are not drawn, when they are not."""
    objectives: tuple[str, ...] = ()
    """The objectives lambda weights, in order (named in every table)."""


WALK_EVALUATION = TaskEvaluation(
    table="Table II (walking)",
    columns={"stride_length": "Avg. Stride (m)", "push_deviation": "Traj. Deviation (m)", "fall_rate": "Falls (%)",
             "forward_step": "Forward step (m)", "side_step": "Side step (m)", "cadence": "Cadence (1/s per foot)",
             "air_time": "Air time, median (s)", "backward_touchdowns": "Backward touchdowns (%)",
             "forward_speed": "Forward speed (m/s)",
             "air_time_left": "Swing left, median (s)", "air_time_right": "Swing right, median (s)",
             "swing_ratio": "Swing L/R ratio", "forward_step_left": "Forward step left (m)",
             "forward_step_right": "Forward step right (m)", "step_ratio": "Step L/R ratio",
             "heading_drift_median": "Heading drift, median (deg)", "heading_drift_p90": "Heading drift, p90 (deg)",
             "lateral_drift": "Lateral drift (m)",
             "base_height": "Pelvis height (m)", "knee_flexion": "Knee flexion (deg)",
             "knee_torque_rms": "Knee torque RMS (Nm; motor rated 139)",
             "strong/fall_rate": "Falls, strong pushes (%)",
             "force-mild/fall_rate": "Falls, 300-600 N on torso or pelvis (%)",
             "force-mild/push_deviation": "Traj. deviation, 300-600 N (m)",
             "force-legs/fall_rate": "Falls, 100-300 N on the legs (%)"},
    front=(("push_deviation", -1.0), ("stride_length", 1.0)),
    reference_point=(-2.0, 0.0),
    push_presets=["mild", "strong", "force-mild", "force-legs"],
    pushes={"mild": PushPreset(1.0, speed=0.5), "strong": PushPreset(1.0, speed=2.25),
            "mild-v1": PushPreset(1.0, speed=0.5), "strong-v1": PushPreset(1.0, speed=1.2),
            "force-mild": PushPreset(1.0, force=(300.0, 600.0)), "force-strong": PushPreset(1.0, force=(600.0, 900.0)),
            "force-legs": PushPreset(1.0, force=(100.0, 300.0), bodies=LEGS)},
    command=(0.5, 0.0, 0.0),
    objectives=("disturbance", "stride"),
    # Table II: (trajectory deviation m, avg. stride m); its (1, 0) row is printed (0.10, 0.00), a typo
    paper_front={(1.0, 0.0): (0.23, 0.42), (0.75, 0.25): (0.29, 0.55), (0.5, 0.5): (0.33, 0.67),
                 (0.25, 0.75): (0.51, 0.72), (0.0, 1.0): (0.85, 0.79)},
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
        "force-mild/com_displacement": "COM displacement, 300-600 N (m)",
        "force-mild/success": "Success, 300-600 N (%)",
        "force-strong/success": "Success, 700-1000 N (%)",
    },
    front=(("energy_overall", -1.0), ("mild/com_displacement", -1.0)),
    reference_point=(-3000.0, -3.0),
    push_presets=["mild", "strong", "force-mild", "force-strong"],
    pushes={"mild": PushPreset(3.0, speed=2.25), "strong": PushPreset(3.0, speed=2.5),
            "mild-v1": PushPreset(1.0, speed=0.5), "strong-v1": PushPreset(1.0, speed=1.2),
            "force-mild": PushPreset(3.0, force=(300.0, 600.0), duration_s=0.1),
            "force-strong": PushPreset(3.0, force=(700.0, 1000.0), duration_s=0.1)},
    push_only_when_standing=True,
    paper_note="Table I's energy is in J, ours in J/s (mean power): its points are not drawn.",
    objectives=("energy", "disturbance"),
)


TOY_EVALUATION = TaskEvaluation(
    table="Toy task (two goals)",
    columns={"goal_a": "Return goal A (undiscounted)", "goal_b": "Return goal B (undiscounted)"},
    front=(("goal_a", 1.0), ("goal_b", 1.0)),
    reference_point=(-60.0, -60.0),
    push_presets=[],
    episode_returns=True,
    objectives=("goal_a", "goal_b"),
)


PUSH_CALIBRATION = """The presets come from tools/diagnostics/push_sweep.py --calibrate on the first released policies
at (0.5, 0.5) (docs/evaluation.md, "Push presets"): mild is the speed whose deviation after a push comes closest to the
paper's at (0.5, 0.5) while 90% of episodes stay up, strong the speed at which the share that stays up comes closest to
the paper's 75.7%. Fall recovery measures the COM until the next push (3 s), long enough for the robot to settle; the
1 s window of the v1 presets cut the displacement short. The v1 presets (0.5 and 1.2 m/s, 1 s) remain available.
The force presets push as a robot is pushed, by a force over a set time on a body (docs/evaluation.md, "Pushes as
forces"): 300-600 N for 0.08 s on the torso or pelvis is the level of an external benchmark of G1 walking policies
(a punch of up to 600 N for 0.08 s); the legs get 100-300 N."""


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
    cfg = copy.deepcopy(cfg)
    env = cfg.env
    env.randomization.enabled = False
    env.observation_noise = 0.0
    env.preference_resample_prob = 0.0
    if push_preset not in evaluation.pushes:
        raise ValueError(f"push preset '{push_preset}' is not one of {', '.join(evaluation.pushes)}.")
    env.push = evaluation.pushes[push_preset].push_config()
    env.push.only_when_standing = evaluation.push_only_when_standing
    env.command_resample_s = None  # one command per episode: the figures are per command
    if hasattr(env, "curriculum"):
        env.curriculum = False
    if evaluation.command is not None:  # every episode: training's standing episodes would dilute the gait figures
        vx, vy, wz = evaluation.command
        env.steering_ranges = dict(env.command_ranges)  # what pchc-play may still steer (pchc_rsl.viewers.steering)
        env.command_ranges = {"lin_vel_x": (vx, vx), "lin_vel_y": (vy, vy), "ang_vel_z": (wz, wz)}
        # standing, straight and one-axis draws: each would replace the named command
        env.zero_command_probability = env.zero_yaw_rate_probability = env.single_axis_probability = 0.0
    return cfg

