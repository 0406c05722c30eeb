"""The PPO setup both G1 tasks share: CPU-sized defaults (64 envs), 24-step rollouts, the AMP style reward.

Update cost: 3 PPO epochs (not rsl-rl's 5), experts of [128, 64] (not [256, 128]) and a critic of [256, 128] (not
[256, 256, 128]). Measured on g1-walk-fast at 1024 envs (docs/results/training_speed.md): the update costs about a
third as much, and the reward rises faster per hour and no slower per env step. Fall recovery shares the setting
(not measured there).
"""

from __future__ import annotations

from pchc_rsl.configs.base import (AMPConfig, AlgorithmConfig, RunnerConfig, SymmetryConfig, TaskConfig, default_actor,
                                  default_critic)


def g1_task_config(name: str, env_class: str, env, experiment_name: str, symmetry: bool = False) -> TaskConfig:
    """A TaskConfig for a G1 env config: PCI actor over its history frames, AMP over its actuated joints; with
    ``symmetry``, rsl-rl's symmetry extension on the G1's left-right mirror (mirrored samples in every mini-batch
    and the mirror loss)."""
    actor = default_actor()
    actor.hidden_dims = [128, 64]  # per expert
    actor.kwargs |= {"history_length": env.history_length}
    critic = default_critic()
    critic.hidden_dims = [256, 128]
    return TaskConfig(
        name=name,
        env_class=env_class,
        env=env,
        num_envs=64,
        runner=RunnerConfig(
            experiment_name=experiment_name,
            num_steps_per_env=24,
            max_iterations=3000,
            save_interval=50,
            algorithm=AlgorithmConfig(
                num_learning_epochs=3,
                entropy_coef=0.01,  # mjlab's G1 velocity task and HoST
                reward_group_names=["task", *env.objective_names],
                amp_cfg=AMPConfig(joint_names=list(env.joints), window=env.amp_window),
                symmetry_cfg=SymmetryConfig("pchc_rsl.envs.g1.symmetry:augment_with_mirror", use_data_augmentation=True,
                                            use_mirror_loss=True, mirror_loss_coeff=1.0) if symmetry else None,
            ),
            actor=actor,
            critic=critic,
        ),
    )
