"""G1 fall recovery from prone: energy efficiency vs disturbance resistance (the paper's Table I task).

HoST trains four critics (task, style, regularisation, post-task); here all preference-invariant terms are folded
into the single task group, because MultiCriticPPO's contract is one task critic plus one per objective and the
relative scale of the folded terms is set directly by their weights below.
"""

from __future__ import annotations

from pchc_rsl.configs.base import TaskConfig
from pchc_rsl.configs.g1_training import g1_task_config
from pchc_rsl.envs.g1.env import PushConfig, RandomizationConfig, RewardTerm
from pchc_rsl.envs.g1.fall_recovery import FallRecoveryConfig
from pchc_rsl.envs.physics.warp_settings import WarpSettings
from pchc_rsl.robots.g1.constants import FALL_RECOVERY_HELD_JOINTS, FALL_RECOVERY_JOINTS

R = "pchc_rsl.envs.g1.rewards:"


def fall_recovery_rewards() -> list[RewardTerm]:
    return [
        # task: get up and stay upright
        RewardTerm(R + "pelvis_height", 3.0, params={"target": 0.72}),
        RewardTerm(R + "upright", 1.0),
        # post-standing target posture
        RewardTerm(R + "standing_posture", 1.0, params={"min_height": 0.65, "std": 1.0}),
        # regularisation and style
        RewardTerm(R + "action_rate", -0.01),
        RewardTerm(R + "joint_limits", -5.0),
        # objectives, raw; a fall after standing costs 5 of energy return and 10 of disturbance return (it ends
        # the episode, and with it both costs): docs/design.md, "Fall costs". r_disturb charges the whole-body COM,
        # the point Table I measures: docs/design.md, "The COM option of r_disturb".
        RewardTerm(R + "energy", 1.0, group="energy", params={"k_tau": 1e-4, "k_p": 1e-3, "fall_cost": 5.0}),
        RewardTerm(R + "disturbance", 1.0, group="disturbance", params={"fall_cost": 10.0, "com": True}),
    ]


def fall_recovery_env(fast: bool = False) -> FallRecoveryConfig:
    return FallRecoveryConfig(
        joints=list(FALL_RECOVERY_JOINTS),
        timestep=0.005 if fast else 0.002,
        decimation=4 if fast else 10,
        initial_joint_noise=0.3,
        objective_names=["energy", "disturbance"],
        rewards=fall_recovery_rewards(),
        held_joints=list(FALL_RECOVERY_HELD_JOINTS),  # as the robot holds them (pchc-deploy)
        # pushes test the stood-up robot (r_disturb, COM displacement); HoST trains getting up without pushes. The
        # range spans the calibrated evaluation presets (mild 2.25, strong 2.5 m/s). r_disturb is charged over the
        # 3 s after a push, the window in which the evaluation measures the COM displacement: docs/design.md,
        # "The 3 s disturbance window".
        push=PushConfig(velocity=(0.5, 2.75), only_when_standing=True, window_s=3.0),
        action_delay_s=(0.0, 0.02),  # a robot's 0-20 ms from sensing to actuation
        randomization=RandomizationConfig(added_base_mass=(-1.0, 5.0), actuator_strength=(0.8, 1.1)),
        critic_push_timing=True,  # the critic sees the time left in the push window and to the next push
        preference_concentration=0.5,  # more training preferences near the ends (docs/design.md)
        terminate_on_fall=True,
        assist_level_step=0.1,  # HoST: 20 of 200 N per step
        # its robots lie, kick and get up for most of an episode: more room than walking (peak 61 rows, 14 contacts)
        warp=WarpSettings(constraints_per_env=192, contacts_per_env=48),
    )


def g1_fall_recovery_task(fast: bool = False) -> TaskConfig:
    env = fall_recovery_env(fast)
    name = "g1-fall-recovery-fast" if fast else "g1-fall-recovery"
    return g1_task_config(name, "pchc_rsl.envs.g1.fall_recovery:G1FallRecoveryEnv", env, "g1_fall_recovery")


def g1_fall_recovery_fast_task() -> TaskConfig:
    return g1_fall_recovery_task(fast=True)
