"""Physical randomisation of the G1 as a bounded set of model variants shared by the envs."""

from __future__ import annotations

import copy

import mujoco
import numpy as np

from pchc_rsl.envs.g1.config import RandomizationConfig


def model_variants(model: mujoco.MjModel, cfg: RandomizationConfig, num_envs: int,
                   rng: np.random.Generator) -> list[mujoco.MjModel]:
    """One model per env for ``mujoco.rollout``: min(num_envs, V) randomised copies, env i gets copy i mod V.

    Each copy draws, uniformly: the floor's sliding friction, a mass added to the pelvis, and one strength factor
    scaling kp and kd of every actuator. Without randomisation every env shares ``model`` itself.
    """
    if not cfg.enabled:
        return [model] * num_envs
    if cfg.num_model_variants < 1:
        raise ValueError(f"num_model_variants must be >= 1, got {cfg.num_model_variants}.")
    floor, base = model.geom("floor").id, model.body("pelvis").id
    variants = []
    for _ in range(min(num_envs, cfg.num_model_variants)):
        m = copy.copy(model)
        m.geom_friction[floor, 0] = rng.uniform(*cfg.friction)
        m.body_mass[base] += rng.uniform(*cfg.added_base_mass)
        strength = rng.uniform(*cfg.actuator_strength)
        m.actuator_gainprm[:, 0] *= strength
        m.actuator_biasprm[:, 1:3] *= strength
        mujoco.mj_setConst(m, mujoco.MjData(m))  # masses derived from body_mass (subtree masses: the COM sensor)
        variants.append(m)
    return [variants[i % len(variants)] for i in range(num_envs)]
