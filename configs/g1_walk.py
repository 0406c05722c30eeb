"""G1 walking: disturbance resistance vs stride length (the paper's Table II task, in its order)."""

from __future__ import annotations

from pchc_rsl.configs.base import TaskConfig
from pchc_rsl.configs.g1_training import g1_task_config
from pchc_rsl.envs.g1.env import G1EnvConfig, PushConfig, RandomizationConfig, RewardTerm
from pchc_rsl.robots.g1.constants import WALK_HELD_JOINTS, WALK_JOINTS

R = "pchc_rsl.envs.g1.rewards:"


def walk_rewards() -> list[RewardTerm]:
    """Task terms after mjlab's G1 velocity task (src/mjlab/tasks/velocity/velocity_env_cfg.py and
    config/g1/env_cfgs.py), foot clearance -2.0; mjlab's upright and posture terms reward staying up, ``alive``
    stands in for them here. Tracking weighs twice mjlab's 2.0: at mjlab's weights the walker turned at half the
    commanded rate and, at lambda = (1, 0), walked 0.3 m/s when told 0.5 (docs/design.md, "Why the walker turned too
    slowly: side by side"); the heading hold's kernel is 0.1 rad wide, so that a few degrees off cost, and the
    position hold charges the distance from where the commands take the robot (docs/design.md, beside the heading
    hold).

    Gait terms, against hopping (both feet leaving the ground together): legged_gym's air-time term, which charges
    every swing shorter than 0.3 s and pays longer ones up to 0.5 s (weight 8; docs/design.md, "Gait terms"), a
    single-stance term that pays the feet taking turns, and unitree_rl_gym's G1 hip_pos penalty on hip roll and yaw
    against straddling (``backward_touchdown`` and a task-group ``fall`` cost are left out: docs/design.md). The
    objectives are the paper's equations: r_stride read per stance step and paid at the commanded speed
    (docs/design.md, "The stride speed gate"), each step as the step its cadence makes at the commanded speed
    (``commanded_length``), r_disturb with a fall costing 5 (docs/design.md, "Fall costs")."""
    return [
        RewardTerm(R + "track_lin_vel_xy", 4.0, params={"std": 0.5}),
        RewardTerm(R + "track_lin_vel_xy", 1.0, params={"std": 0.15}),
        RewardTerm(R + "track_ang_vel_z", 3.0, params={"std": 0.5}),
        RewardTerm(R + "track_ang_vel_z", 3.0, params={"std": 0.15}),
        RewardTerm(R + "track_average_lin_vel_xy", 2.0, params={"std": 0.1}),
        RewardTerm(R + "track_average_yaw_rate", 2.0, params={"std": 0.1}),
        RewardTerm(R + "heading_hold", 3.0, params={"std": 0.1}),
        RewardTerm(R + "position_hold", 3.0, params={"std": 0.25}),
        RewardTerm(R + "flat_orientation", -5.0),
        RewardTerm(R + "base_height", -10.0, params={"target": 0.74}),
        RewardTerm(R + "feet_slip", -0.1),
        RewardTerm(R + "feet_clearance", -2.0, params={"target_height": 0.1}),
        RewardTerm(R + "feet_air_time", 8.0, params={"threshold": 0.3, "max_air": 0.5}),
        RewardTerm(R + "single_stance", 2.0),
        RewardTerm(R + "joint_deviation", -1.0, params={"joints": ["hip_roll", "hip_yaw"]}),
        RewardTerm(R + "joint_limits", -5.0),
        RewardTerm(R + "torques", -1e-5),
        RewardTerm(R + "action_rate", -0.01),
        RewardTerm(R + "alive", 1.0),
        RewardTerm(R + "disturbance", 1.0, group="disturbance", params={"fall_cost": 5.0}),
        RewardTerm(R + "stride", 1.0, group="stride",
                   params={"speed_std": 0.25, "along_command": True, "fall_cost": 0.0, "commanded_length": True}),
    ]


def walk_env(fast: bool = False) -> G1EnvConfig:
    """Paper physics: 500 Hz PD, 50 Hz policy. ``fast``: timestep 0.005, decimation 4 (HoST, mjlab)."""
    return G1EnvConfig(
        joints=list(WALK_JOINTS),
        # the waist and wrists as the robot holds them (pchc-deploy): docs/design.md, "Held joints"
        held_joints=list(WALK_HELD_JOINTS),
        timestep=0.005 if fast else 0.002,
        decimation=4 if fast else 10,
        use_command=True,
        action_scale_per_joint=True,  # mjlab's G1: 0.25 * effort / kp, 0.35-0.55 rad per unit action
        command_ranges={"lin_vel_x": (-0.5, 1.0), "lin_vel_y": (-0.5, 0.5), "ang_vel_z": (-1.0, 1.0)},
        zero_command_probability=0.15,  # standing still is a command too (the evaluation's 0 m/s)
        zero_yaw_rate_probability=0.3,  # walking straight: holding a heading is trained, not only turning
        single_axis_probability=0.3,  # a pure side step or turn on the spot, as an operator's stick gives
        command_resample_s=(4.0, 8.0),  # steered within an episode, as an operator does
        action_delay_s=(0.0, 0.02),  # a robot's 0-20 ms from sensing to actuation
        push=PushConfig(velocity=(0.3, 2.0)),  # spans the evaluation presets, mild to strong
        randomization=RandomizationConfig(added_base_mass=(-1.0, 5.0), actuator_strength=(0.8, 1.1)),
        objective_names=["disturbance", "stride"],  # Table II's order: lambda = (0, 1) prioritises stride
        rewards=walk_rewards(),
        termination_height=0.45,
        critic_command_state=True,  # the critics see how far the robot is off its commanded path
    )


def g1_walk_task(fast: bool = False) -> TaskConfig:
    """The walking task as the released walker trains (docs/results/g1_walk.md, "Recipe and lineage"): the
    disturbance end draws half the action noise the stride end draws (docs/design.md, "Action noise")."""
    env = walk_env(fast)
    cfg = g1_task_config("g1-walk-fast" if fast else "g1-walk", "pchc_rsl.envs.g1.env:G1Env", env, "g1_walk",
                         symmetry=True)
    cfg.runner.actor.kwargs |= {"objective_noise_scales": [0.5, 1.0]}
    return cfg


def g1_walk_fast_task() -> TaskConfig:
    return g1_walk_task(fast=True)
