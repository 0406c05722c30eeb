"""Module paths a saved config may name from before the envs were grouped by task and physics, and their names now.

A checkpoint stores its config as plain data, with reward terms, the symmetry function and the env class named as
``"module:attribute"`` strings; a checkpoint trained before the move still loads, evaluates and resumes.
"""

from __future__ import annotations

MOVED_MODULES = {
    "pchc_rsl.envs.commanded_path": "pchc_rsl.envs.g1.commanded_path",
    "pchc_rsl.envs.g1_config": "pchc_rsl.envs.g1.config",
    "pchc_rsl.envs.g1_contacts": "pchc_rsl.envs.g1.contacts",
    "pchc_rsl.envs.g1_env": "pchc_rsl.envs.g1.env",
    "pchc_rsl.envs.g1_fall_recovery": "pchc_rsl.envs.g1.fall_recovery",
    "pchc_rsl.envs.g1_metrics": "pchc_rsl.envs.g1.metrics",
    "pchc_rsl.envs.g1_observations": "pchc_rsl.envs.g1.observations",
    "pchc_rsl.envs.g1_pushes": "pchc_rsl.envs.g1.pushes",
    "pchc_rsl.envs.g1_randomization": "pchc_rsl.envs.g1.randomization",
    "pchc_rsl.envs.g1_render": "pchc_rsl.envs.g1.render",
    "pchc_rsl.envs.g1_rewards": "pchc_rsl.envs.g1.rewards",
    "pchc_rsl.envs.g1_robot_state": "pchc_rsl.envs.g1.robot_state",
    "pchc_rsl.envs.g1_symmetry": "pchc_rsl.envs.g1.symmetry",
    "pchc_rsl.envs.reward_groups": "pchc_rsl.envs.g1.reward_groups",
    "pchc_rsl.envs.physics": "pchc_rsl.envs.physics.batched_mujoco",
    "pchc_rsl.envs.physics_backend": "pchc_rsl.envs.physics.backend",
    "pchc_rsl.envs.physics_mirror": "pchc_rsl.envs.physics.mirror",
    "pchc_rsl.envs.physics_warp": "pchc_rsl.envs.physics.warp_mujoco",
    "pchc_rsl.envs.warp_device": "pchc_rsl.envs.physics.warp_device",
    "pchc_rsl.envs.warp_settings": "pchc_rsl.envs.physics.warp_settings",
}


def current_name(value: str) -> str:
    """``"old.module:attr"`` -> ``"new.module:attr"`` for a moved module; anything else unchanged."""
    module, sep, attribute = value.partition(":")
    return MOVED_MODULES[module] + sep + attribute if sep and module in MOVED_MODULES else value


def with_current_names(saved):
    """A copy of saved plain data (dicts, lists, strings, numbers) with every moved ``module:attr`` renamed."""
    if isinstance(saved, dict):
        return {key: with_current_names(value) for key, value in saved.items()}
    if isinstance(saved, (list, tuple)):
        return type(saved)(with_current_names(value) for value in saved)
    return current_name(saved) if isinstance(saved, str) else saved
