"""MO-Gymnasium tasks: PCHC on environments nobody here wrote.

``mo-hopper-2obj-v5`` (forward, height), ``mo-halfcheetah-v5`` (forward, energy), ``mo-walker2d-v5`` (forward,
energy) and ``mo-hopper-v5`` (forward, height, energy: three objectives, Dirichlet routing on the 2-simplex).
PPO settings follow the usual MuJoCo-locomotion PPO (2048 transitions per update, 10 epochs, small networks, no
entropy bonus) rather than the G1's massively parallel ones. Nothing else is special: these envs have no
preference-invariant reward, and MultiCriticPPO drops the all-zero task group by itself; value normalisation makes
value clipping and the loss independent of the returns' scale (hundreds to thousands here), so rewards stay raw.
"""

from __future__ import annotations

from pchc_rsl.configs.base import AlgorithmConfig, RunnerConfig, TaskConfig, default_actor, default_critic
from pchc_rsl.envs.mo_gym import MOGymEnvConfig

REFERENCE_POINTS = {
    # Below every return a policy that moves at all reaches in 1000 steps; energy objectives: -sum a^2 per step
    # (6 actuators in [-1, 1] for halfcheetah and walker2d, 3 for hopper) plus the healthy reward where the env
    # adds it to every objective (walker2d, hopper).
    "mo-hopper-2obj-v5": (-100.0, -100.0),
    "mo-halfcheetah-v5": (-100.0, -6000.0),
    "mo-walker2d-v5": (-100.0, -5000.0),
    "mo-hopper-v5": (-100.0, -100.0, -2000.0),
}
"""Task -> the reference point of the hypervolume of its fronts."""
OBJECTIVE_RANGES = {
    # (low, high) per objective for the expected utility. low: the reference point. high: energy 0 (no action) plus
    # the healthy reward where the env adds it (1 per step for 1000 steps); forward and height: a bound no policy
    # in these studies reaches in 1000 steps (their best returns are below 4000 on every task).
    "mo-hopper-2obj-v5": ((-100.0, -100.0), (4000.0, 4000.0)),
    "mo-halfcheetah-v5": ((-100.0, -6000.0), (5000.0, 0.0)),
    "mo-walker2d-v5": ((-100.0, -5000.0), (6000.0, 1000.0)),
    "mo-hopper-v5": ((-100.0, -100.0, -2000.0), (4000.0, 4000.0, 1000.0)),
}
"""Task -> (low, high) of each objective's return, which the expected utility normalises by."""


def _mo_gym_task(name: str, env: MOGymEnvConfig) -> TaskConfig:
    actor = default_actor()
    actor.hidden_dims = [64, 64]
    actor.distribution_cfg["init_std"] = 0.6
    actor.kwargs |= {"history_length": env.history_length}
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
                reward_group_names=["task", *env.objective_names],
            ),
            actor=actor,
            critic=critic,
        ),
    )


def mo_hopper_task() -> TaskConfig:
    env = MOGymEnvConfig(env_id="mo-hopper-2obj-v5", objective_names=["forward", "height"])
    return _mo_gym_task("mo-hopper-2obj-v5", env)


def mo_halfcheetah_task() -> TaskConfig:
    env = MOGymEnvConfig(env_id="mo-halfcheetah-v5", objective_names=["forward", "energy"])
    return _mo_gym_task("mo-halfcheetah-v5", env)


def mo_walker2d_task() -> TaskConfig:
    env = MOGymEnvConfig(env_id="mo-walker2d-v5", objective_names=["forward", "energy"])
    return _mo_gym_task("mo-walker2d-v5", env)


def mo_hopper_3obj_task() -> TaskConfig:
    env = MOGymEnvConfig(env_id="mo-hopper-v5", objective_names=["forward", "height", "energy"])
    return _mo_gym_task("mo-hopper-v5", env)
