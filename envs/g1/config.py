"""Typed configuration of the G1 environments: reward terms, pushes, randomisation and the env itself."""

from __future__ import annotations

from dataclasses import dataclass, field

from pchc_rsl.envs.physics.warp_settings import WarpSettings


@dataclass
class RewardTerm:
    func: str
    """``"module:function"``; called as func(env, **params) -> Tensor[N]."""
    weight: float
    group: str = "task"
    """"task" (preference-invariant) or one of the config's objective names."""
    params: dict = field(default_factory=dict)


@dataclass
class ForcePushConfig:
    """Pushes as a hand, a door or a person gives them: a force on one body of the robot over tenths of a second
    (MuJoCo's xfrc_applied, at the body's centre of mass), which moves the robot and turns it."""

    share: float = 0.0
    """Weight of force pushes among all pushes, against ``PushConfig.velocity_share``; 0: none."""
    bodies: dict[str, float] = field(default_factory=lambda: {"torso_link": 1.0, "pelvis": 1.0})
    """Body name -> weight of being the body pushed."""
    magnitude: tuple[float, float] = (300.0, 600.0)
    """The force's magnitude, N, uniform in this range."""
    duration_s: tuple[float, float] = (0.08, 0.08)
    """How long the force lasts, s, uniform in this range; a push's impulse is magnitude x duration (a step that the
    push ends part-way through gets its share of the force, so the impulse is exact)."""
    vertical: tuple[float, float] = (0.0, 0.0)
    """The force's vertical part as a share of its magnitude, uniform in this range (negative: down); the horizontal
    part points in a uniformly random direction."""


@dataclass
class PushConfig:
    """Pushes at random intervals, velocity kicks on the pelvis or forces on a body (``force``), mixed by their
    shares; the window after each push's onset is the paper's 'after-disturb'."""

    enabled: bool = True
    interval_s: tuple[float, float] = (3.0, 6.0)
    velocity: tuple[float, float] = (0.3, 1.0)
    """Horizontal speed added to the pelvis, m/s, uniform in this range, in a uniformly random direction."""
    velocity_share: float = 1.0
    """Weight of velocity kicks among all pushes, against ``force.share``."""
    force: ForcePushConfig = field(default_factory=ForcePushConfig)
    window_s: float = 1.0
    only_when_standing: bool = False
    """Count down to the next push only while the robot stands (fall recovery's evaluation pushes the stood-up
    robot, as in the paper, not the one still on the floor)."""
    reference_turns: bool = True
    """The reference of r_disturb and the push deviation turns at the commanded yaw rate (it follows the commanded
    twist); False: it moves straight at the commanded velocity the push found, the paper's x_last + v_ref t, under
    which turning as told inside a window counts as deviation (docs/design.md, "A reference that turns")."""


@dataclass
class RandomizationConfig:
    """Physical randomisation: ``num_model_variants`` model copies, each with its own uniform draws of the ranges
    below, made when the env is built; env i simulates variant i mod num_model_variants for its whole life.

    Variants keep memory bounded (a lean model is about 0.2 MB) whatever the number of envs.
    """

    enabled: bool = True
    num_model_variants: int = 64
    friction: tuple[float, float] = (0.4, 1.2)
    """Floor sliding friction; the floor's geom priority makes it the contact's friction."""
    added_base_mass: tuple[float, float] = (-1.0, 3.0)
    actuator_strength: tuple[float, float] = (0.9, 1.1)
    """Scale on kp and kd of every actuator."""


@dataclass
class G1EnvConfig:
    joints: list[str]
    held_joints: list[str] = field(default_factory=list)
    """Joints the policy does not drive that are held at the default pose by a spring-damper with the robot's
    holding gains (as pchc-deploy holds them on the robot) instead of welded; empty: every other joint welded."""
    physics: str = "mujoco"
    """The physics backend: "mujoco" (C MuJoCo on the CPU threads) or "warp" (MuJoCo Warp on the training device;
    the ``warp`` extra)."""
    warp: WarpSettings = field(default_factory=WarpSettings)
    """MuJoCo Warp's per-world buffers and solver iterations (``env.warp.constraints_per_env=...``)."""
    timestep: float = 0.002
    decimation: int = 10
    episode_length_s: float = 10.0
    num_threads: int = 1
    action_scale: float = 0.25
    """eta: q_target = q_default + eta * w_j * a."""
    action_scale_per_joint: bool = False
    """w_j = effort limit / kp of joint j (mjlab's G1 rule: with eta = 0.25, a = 1 asks for a quarter of the joint's
    torque limit); False: w_j = 1 (radians)."""
    action_clip: float = 10.0
    action_delay_s: tuple[float, float] = (0.0, 0.0)
    """Delay from the policy's action to the actuators, s: drawn per env at every reset, uniformly over the whole
    physics substeps in this range (sim-to-real G1 work trains with 0-20 ms). For the first d substeps of a policy
    step the actuators still hold the previous target. At most one policy step (timestep * decimation)."""
    history_length: int = 5
    amp_window: int = 5
    """Frames of actuated joint positions in the ``amp`` observation group (the AMP state window)."""
    amp_root_velocity: bool = False
    """Each amp frame also holds the base's velocity in its heading frame (forward, sideways, yaw rate), read as the
    change over the step, as the clips' is over a frame (pchc_rsl.amp.motion.root_velocity). Joint angles alone pay
    stepping in place as they pay walking (docs/design.md, "A style reward that pulls"). Changes the discriminator's
    input: a run started from a checkpoint without it needs ``--fresh-discriminator``."""
    observation_noise: float = 1.0
    """Multiplies the per-quantity noise scales (0 turns noise off)."""
    command_ranges: dict[str, tuple[float, float]] = field(
        default_factory=lambda: {"lin_vel_x": (0.0, 0.0), "lin_vel_y": (0.0, 0.0), "ang_vel_z": (0.0, 0.0)}
    )
    zero_command_probability: float = 0.0
    """Share of commands that are zero (standing still), drawn with each command on top of command_ranges."""
    zero_yaw_rate_probability: float = 0.0
    """Share of the other commands whose yaw rate is zero (walking straight)."""
    single_axis_probability: float = 0.0
    """Share of the other commands that move one axis alone, v_x, v_y or w_z with equal chance (a pure side step, turn
    on the spot or straight walk), as an operator's stick often does; drawn uniformly, pure side steps and turns on
    the spot are almost never trained. What it changes: docs/design.md, "Action noise"."""
    velocity_average_s: float = 0.5
    """Time constant (s) of ``VelocityCommands.velocity_average``, the base's velocity with the gait's sway filtered
    out."""
    command_resample_s: tuple[float, float] | None = None
    """Draw a new command after a time uniform in this range (s), again and again within an episode, as a robot is
    steered; None: one command per episode, drawn at the reset."""
    use_command: bool = False
    """Whether the policy observes the velocity command (walking)."""
    initial_joint_noise: float = 0.1
    push: PushConfig = field(default_factory=PushConfig)
    randomization: RandomizationConfig = field(default_factory=RandomizationConfig)
    objective_names: list[str] = field(default_factory=lambda: ["obj_1", "obj_2"])
    rewards: list[RewardTerm] = field(default_factory=list)
    critic_push_timing: bool = False
    """Also give the critic the time left in the push window and until the next push. r_disturb's value depends on
    both; without them its critic cannot predict it, and its advantage (normalised to unit scale) is mostly noise.
    Changes the critic's input size: checkpoints trained without it do not load with it."""
    critic_push_size: bool = False
    """Also give the critic the push's size, as the horizontal velocity it gives the whole robot (m/s), inside its
    window. The deviation a push leaves grows with its size, which is drawn over a wide range (forces of 300-1000 N
    for 0.1 s give a 33 kg robot 0.9-3.0 m/s); without it the critic sees where the push went, not how hard it was,
    and the disturbance advantage carries the draw's luck. Changes the critic's input size (``pchc-train
    --init-from`` widens a checkpoint's critics with zero weights for it)."""
    critic_command_state: bool = False
    """Also give the critic the state that the task's holds read: the base's offset from the commanded path (in the
    base's heading frame), the heading error and the averaged velocity. position_hold, heading_hold and the average
    kernels pay by them; without them the critic cannot tell a walker that has drifted off its path from one on it,
    and the cost of a drift (seconds of lower pay) reaches the advantage only through the lambda-return's short tail.
    Changes the critic's input size: ``pchc-train --init-from`` widens a critic trained without it."""
    preference_concentration: float = 1.0
    preference_resample_prob: float = 0.0
    """Per-step probability of re-sampling lambda mid-episode."""
    termination_height: float = 0.4
    termination_tilt: float = 0.8
    """Terminate when the horizontal part of gravity in the base frame exceeds this (|g_xy|, g = 1)."""
    contact_force_threshold: float = 1.0
    planted_foot_height: float = 0.03
    """At a reset, a foot whose sole site is below this height (m) counts as already on the ground: the initial
    joint noise leaves one foot hovering a few mm, and its settling must not count as a touchdown (a stride)."""
