"""Typed configuration shared by every task: algorithm, models and runner, turned into rsl-rl's config dict."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

ACTOR_CLASSES = {
    "pci": "pchc_rsl.modules:PCIActor",
    "gated": "pchc_rsl.modules:GatedMoEActor",
    "mlp": "pchc_rsl.modules:PreferenceMLPModel",
}
"""Short names for the actor variants the CLI offers (PCI, the learned-gate ablation, a plain MLP)."""


@dataclass
class AlgorithmConfig:
    class_name: str = "pchc_rsl.algorithms:MultiCriticPPO"
    num_learning_epochs: int = 5
    num_mini_batches: int = 4
    clip_param: float = 0.2
    gamma: float = 0.99
    lam: float = 0.95
    value_loss_coef: float = 1.0
    entropy_coef: float = 0.005
    learning_rate: float = 1e-3
    max_grad_norm: float = 1.0
    schedule: str = "adaptive"
    desired_kl: float = 0.01
    reward_group_names: list[str] | None = None
    """Names of the critics for logging: task first, then each objective."""


@dataclass
class ModelConfig:
    class_name: str
    hidden_dims: list[int] = field(default_factory=lambda: [256, 128])
    activation: str = "elu"
    obs_normalization: bool = True
    distribution_cfg: dict | None = None
    kwargs: dict[str, Any] = field(default_factory=dict)
    """Class-specific arguments (e.g. num_experts, routing_scale, history_length for the PCI actor)."""

    def to_dict(self) -> dict:
        d = {k: v for k, v in dataclasses.asdict(self).items() if k != "kwargs"}
        if d["distribution_cfg"] is None:
            del d["distribution_cfg"]
        return {**d, **self.kwargs}


def default_actor() -> ModelConfig:
    return ModelConfig(
        class_name=ACTOR_CLASSES["pci"],
        distribution_cfg={"class_name": "rsl_rl.modules:GaussianDistribution", "init_std": 1.0, "std_type": "log"},
    )


def default_critic() -> ModelConfig:
    return ModelConfig(class_name=ACTOR_CLASSES["mlp"], hidden_dims=[256, 256, 128])


@dataclass
class RunnerConfig:
    experiment_name: str
    num_steps_per_env: int = 24
    max_iterations: int = 1000
    save_interval: int = 100
    obs_groups: dict[str, list[str]] = field(
        default_factory=lambda: {"actor": ["policy", "preference"], "critic": ["critic", "preference"]}
    )
    algorithm: AlgorithmConfig = field(default_factory=AlgorithmConfig)
    actor: ModelConfig = field(default_factory=default_actor)
    critic: ModelConfig = field(default_factory=default_critic)

    def to_rsl_rl(self) -> dict:
        """The train_cfg dict OnPolicyRunner expects."""
        return {
            "num_steps_per_env": self.num_steps_per_env,
            "save_interval": self.save_interval,
            "obs_groups": {k: list(v) for k, v in self.obs_groups.items()},
            "algorithm": dataclasses.asdict(self.algorithm),
            "actor": self.actor.to_dict(),
            "critic": self.critic.to_dict(),
            "logger": "tensorboard",
            "experiment_name": self.experiment_name,
        }


@dataclass
class TaskConfig:
    name: str
    env_class: str
    """``"module:Class"`` of the VecEnv; constructed as Class(env, num_envs, device, seed)."""
    env: Any
    runner: RunnerConfig
    num_envs: int = 64
    seed: int = 1
    device: str = "cpu"

    def to_dict(self) -> dict:
        """Plain-data view of the whole config (saved next to and inside every checkpoint)."""
        return {
            "task": self.name,
            "env_class": self.env_class,
            "env": dataclasses.asdict(self.env),
            "runner": dataclasses.asdict(self.runner),
            "num_envs": self.num_envs,
            "seed": self.seed,
            "device": self.device,
        }
