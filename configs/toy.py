"""The ``toy`` task: the two-goal point mass, sized to learn in seconds on a CPU."""

from __future__ import annotations

from pchc_rsl.configs.base import AlgorithmConfig, RunnerConfig, TaskConfig, default_actor, default_critic
from pchc_rsl.envs.toy import ToyEnvConfig


def toy_task() -> TaskConfig:
    actor = default_actor()
    actor.hidden_dims = [64, 64]
    actor.distribution_cfg["init_std"] = 0.3
    actor.kwargs |= {"history_length": 5, "encoder_hidden_dims": [32], "history_latent_dim": 8}
    critic = default_critic()
    critic.hidden_dims = [64, 64]
    env = ToyEnvConfig()
    return TaskConfig(
        name="toy",
        env_class="pchc_rsl.envs.toy:ToyEnv",
        env=env,
        num_envs=64,
        runner=RunnerConfig(
            experiment_name="toy",
            num_steps_per_env=env.episode_length,
            max_iterations=60,
            save_interval=50,
            algorithm=AlgorithmConfig(
                gamma=0.95,
                learning_rate=3e-3,
                entropy_coef=0.0,
                reward_group_names=["task", *env.objective_names],
                # the toy's task term is a tiny action cost: at weight 1 its normalised advantage would be mostly
                # value noise as large as the objectives' signal
                task_advantage_weight=0.1,
            ),
            actor=actor,
            critic=critic,
        ),
    )
