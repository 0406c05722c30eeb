"""MO-Gymnasium tasks (``mo-hopper-2obj-v5``, ``mo-halfcheetah-v5``): PCHC on environments nobody here wrote.

PPO settings follow the usual MuJoCo-locomotion PPO (2048 transitions per update, 10 epochs, small networks, no
entropy bonus) rather than the G1's massively parallel ones. These envs have no preference-invariant reward, so the
task group is zero and its advantage weight is 0 (its normalised advantage would be pure value noise).
"""

from __future__ import annotations

from pchc_rsl.configs.base import AlgorithmConfig, RunnerConfig, TaskConfig, default_actor, default_critic
from pchc_rsl.envs.mo_gym import MOGymEnvConfig


def _mo_gym_task(name: str, env: MOGymEnvConfig) -> TaskConfig:
    actor = default_actor()
    actor.hidden_dims = [64, 64]
    actor.distribution_cfg["init_std"] = 0.6
    actor.kwargs = {"history_length": env.history_length}
    critic = default_critic()
    critic.hidden_dims = [128, 128]
    num_envs, steps = 16, 128
    return TaskConfig(
        name=name,
        env_class="pchc_rsl.envs.mo_gym:MOGymVecEnv",
        env=env,
        num_envs=num_envs,
        runner=RunnerConfig(
            experiment_name=name,
            num_steps_per_env=steps,
            max_iterations=1_000_000 // (num_envs * steps),  # 1M env steps
            save_interval=100,
            obs_groups={"actor": ["policy", "preference"], "critic": ["critic", "preference"]},
            algorithm=AlgorithmConfig(
                num_learning_epochs=10,
                num_mini_batches=8,
                learning_rate=3e-4,
                desired_kl=0.01,
                entropy_coef=0.0,
                value_loss_coef=0.5,
                max_grad_norm=0.5,
                use_clipped_value_loss=False,
                reward_group_names=["task", *env.objective_names],
                task_advantage_weight=0.0,
            ),
            actor=actor,
            critic=critic,
        ),
    )


def mo_hopper_task() -> TaskConfig:
    env = MOGymEnvConfig(env_id="mo-hopper-2obj-v5", objective_names=["forward", "height"], reward_scale=0.1)
    return _mo_gym_task("mo-hopper-2obj-v5", env)


def mo_halfcheetah_task() -> TaskConfig:
    env = MOGymEnvConfig(env_id="mo-halfcheetah-v5", objective_names=["forward", "energy"], reward_scale=0.1)
    return _mo_gym_task("mo-halfcheetah-v5", env)
