"""Typed configuration shared by every task: algorithm, models and runner, turned into rsl-rl's config dict."""

from __future__ import annotations

import copy
import dataclasses
import inspect
from dataclasses import dataclass, field
from typing import Any

from rsl_rl.utils import resolve_callable

from pchc_rsl.preference import DEFAULT_ROUTING_SCALE

ACTOR_CLASSES = {
    "pci": "pchc_rsl.modules:PCIActor",
    "gated": "pchc_rsl.modules:GatedMoEActor",
    "mlp": "pchc_rsl.modules:PreferenceMLPModel",
    "no-preference": "rsl_rl.models:MLPModel",
}
"""Short names for the actor variants the CLI offers: PCI, the learned-gate ablation, a plain MLP on [obs, lambda],
and rsl-rl's MLP without the preference input (the prior work's single fixed weighting; needs a fixed preference)."""


LOGGERS = {
    "tensorboard": None,
    "wandb": "rsl_rl.utils.wandb_log_writer:WandbLogWriter",
    "neptune": "rsl_rl.utils.neptune_log_writer:NeptuneLogWriter",
}
"""The training loggers rsl-rl's Logger supports: TensorBoard (built in), Weights & Biases and Neptune (their
LogWriters; need ``pip install wandb`` or ``neptune``)."""


@dataclass
class AMPConfig:
    """The AMP style reward (see pchc_rsl.amp.style.AMPStyle); off when there are no motion files."""

    motion_files: list[str] = field(default_factory=list)
    """Motion files or folders (LAFAN1 G1 CSV, npz)."""
    joint_names: list[str] = field(default_factory=list)
    """The AMP state: these joints' positions, in the env's amp window order."""
    window: int = 5
    style_reward_scale: float = 0.02
    """c, per policy step (0.02 = 1.0 per second at 50 Hz, on the scale of the env's dt-weighted terms)."""
    grad_penalty_coef: float = 5.0
    """alpha^d."""
    penalty_on: str = "reference"
    """Where the gradient penalty is taken: "reference" (the AMP paper) or "interpolates" (between reference and
    policy windows: a discriminator that keeps its slope; pchc_rsl.amp.discriminator)."""
    learning_rate: float = 1e-4
    num_updates: int = 4
    batch_size: int = 512
    replay_capacity: int = 100_000
    """Policy windows the discriminator replays (the newest ones)."""
    exclude_reference_beyond: dict[str, float] = field(default_factory=dict)
    """Joint -> bound (rad): clip frames with that joint further from zero are left out of the reference."""
    root_velocity: bool | None = None
    """Each frame also holds the root's velocity in its heading frame (forward, sideways, yaw rate), so that the
    discriminator tells walking from stepping in place; None: as the env's amp observation has it (the G1 env:
    ``env.amp_root_velocity``)."""


@dataclass
class SymmetryConfig:
    """rsl-rl's symmetry extension (rsl_rl.extensions.Symmetry, Mittal et al. 2024): mirrored samples added to every
    mini-batch and/or a loss on the policy disagreeing with its own mirror."""

    data_augmentation_func: str
    """``"module:function"`` (env, obs, actions) -> the batch followed by its mirror, e.g.
    ``"pchc_rsl.envs.g1.symmetry:augment_with_mirror"``."""
    use_data_augmentation: bool = True
    use_mirror_loss: bool = False
    mirror_loss_coeff: float = 0.0


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
    use_clipped_value_loss: bool = True
    """rsl-rl's value clipping by clip_param, applied to the critics' outputs: in the value normaliser's units
    (returns over their running std) when value normalisation is on, as it is by default; in return units without."""
    schedule: str = "adaptive"
    desired_kl: float = 0.01
    reward_group_names: list[str] | None = None
    """Names of the critics for logging: task first, then each objective."""
    task_advantage_weight: float = 1.0
    """w_task in A = w_task A_task + sum_i lambda_i A_obj_i (1 in the paper)."""
    amp_cfg: AMPConfig | None = None
    symmetry_cfg: SymmetryConfig | None = None


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


def select_actor(model: ModelConfig, variant: str) -> None:
    """Switch an actor config to another variant (a key of ACTOR_CLASSES), dropping arguments it does not take."""
    if variant not in ACTOR_CLASSES:
        raise ValueError(f"Unknown actor variant '{variant}'. Known: {', '.join(ACTOR_CLASSES)}.")
    model.class_name = ACTOR_CLASSES[variant]
    accepted = constructor_arguments(model.class_name)
    model.kwargs = {k: v for k, v in model.kwargs.items() if k in accepted}


def constructor_arguments(class_name: str) -> set[str]:
    """The argument names a model class (``module:Class``) accepts."""
    return _init_parameters(resolve_callable(class_name))


def _init_parameters(cls: type) -> set[str]:
    """Names a class's constructor accepts, following ``**kwargs`` up the base classes."""
    names: set[str] = set()
    for klass in cls.__mro__:
        if "__init__" not in vars(klass):
            continue
        parameters = inspect.signature(klass.__init__).parameters.values()
        names |= {p.name for p in parameters if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)}
        if not any(p.kind == p.VAR_KEYWORD for p in parameters):
            break
    return names


def default_actor() -> ModelConfig:
    return ModelConfig(
        class_name=ACTOR_CLASSES["pci"],
        # rsl-rl's Gaussian, sampled without a host sync per step (pchc_rsl/modules/distribution.py); std_range is
        # rsl-rl's default, named so that a run can cap the action noise (docs/design.md, "Action noise")
        distribution_cfg={"class_name": "pchc_rsl.modules.distribution:GaussianDistribution", "init_std": 1.0,
                          "std_type": "log", "std_range": [1e-6, 1e6]},
        kwargs={"routing_scale": DEFAULT_ROUTING_SCALE},  # named, so that checkpoints record it
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
    logger: str = "tensorboard"
    """Where training scalars go: one of LOGGERS (rsl-rl's writers; wandb and neptune also write TensorBoard)."""
    logger_project: str | None = None
    """The W&B or Neptune project (default: experiment_name)."""

    def to_rsl_rl(self) -> dict:
        """The train_cfg dict OnPolicyRunner expects."""
        return {
            "num_steps_per_env": self.num_steps_per_env,
            "save_interval": self.save_interval,
            "obs_groups": {k: list(v) for k, v in self.obs_groups.items()},
            "algorithm": dataclasses.asdict(self.algorithm),
            "actor": self.actor.to_dict(),
            "critic": self.critic.to_dict(),
            "logger": self.logger_cfg(),
            "experiment_name": self.experiment_name,
        }

    def logger_cfg(self) -> str | dict:
        """rsl-rl's ``cfg["logger"]``: "tensorboard", or the dict form naming a LogWriter and its project."""
        if self.logger not in LOGGERS:
            raise ValueError(f"Unknown logger '{self.logger}'; choose one of {', '.join(LOGGERS)}.")
        if LOGGERS[self.logger] is None:
            return self.logger
        return {"class_name": LOGGERS[self.logger], "project_name": self.logger_project or self.experiment_name}


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
    fixed_preference: list[float] | None = None
    """Hold lambda constant during training (the fixed-preference baselines); None samples it per episode."""

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
            "fixed_preference": self.fixed_preference,
        }


def apply_saved(obj: Any, saved: dict) -> None:
    """Overwrite a config dataclass with a saved plain-dict version of it (as written by ``dataclasses.asdict``),
    rebuilding nested dataclasses and lists of them.

    A field the saved dict lacks was added after it was saved: it takes its dataclass default, which new fields
    keep equal to the behaviour before they existed, not the task's current value (a walker saved before
    ``action_delay_s`` existed ran without latency, whatever the task trains with now)."""
    for f in dataclasses.fields(obj):
        if f.name not in saved:
            if f.default is not dataclasses.MISSING:
                setattr(obj, f.name, copy.deepcopy(f.default))
            elif f.default_factory is not dataclasses.MISSING:
                setattr(obj, f.name, f.default_factory())
    for key, value in saved.items():
        if not hasattr(obj, key):
            raise ValueError(f"Saved config has '{key}', which {type(obj).__name__} does not: another version?")
        current = getattr(obj, key)
        if dataclasses.is_dataclass(current) and isinstance(value, dict):
            apply_saved(current, value)
        elif isinstance(current, list) and current and dataclasses.is_dataclass(current[0]):
            setattr(obj, key, [type(current[0])(**item) for item in value])
        else:
            setattr(obj, key, value)
