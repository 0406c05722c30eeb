"""Preference-conditioned rsl-rl models: the PCI actor and the paper's ablations.

All three are rsl_rl.models.MLPModel subclasses that any rsl-rl config can name by class_name:
- ``PCIActor`` ("pchc_rsl.modules:PCIActor"): a history encoder and N_B experts mixed by the
  preference-parameterised Beta (Dirichlet for m > 2) density at fixed expert positions (the paper's PCI).
- ``GatedMoEActor``: the same experts routed by a learned softmax gate over [observation, lambda] ("w/o PCI").
- ``PreferenceMLPModel``: a plain MLP on [observation, lambda] (the "concatenate lambda" baseline, and the
  multi-critic's critic).

The observation groups are concatenated and (optionally) normalised as rsl-rl does; the preference group is
appended raw, never normalised, so lambda keeps its meaning on the simplex.
"""

from __future__ import annotations

import copy
import math

import torch
import torch.nn as nn
from tensordict import TensorDict

from rsl_rl.models import MLPModel
from rsl_rl.modules import MLP, HiddenState
from rsl_rl.utils import resolve_nn_activation, unpad_trajectories

from pchc_rsl.preference import DEFAULT_ROUTING_SCALE, expert_positions_on_simplex, routing_weights, simplex_lattice


class PreferenceMLPModel(MLPModel):
    """MLPModel whose input is [normalised observation groups, raw preference]; subclasses swap the head.

    ``self.mlp`` maps the [N, obs_dim + m] latent to the output, so rsl-rl's forward, distributions and
    normalisation updates work unchanged.
    """

    def __init__(
        self,
        obs: TensorDict,
        obs_groups: dict[str, list[str]],
        obs_set: str,
        output_dim: int,
        hidden_dims: tuple[int, ...] | list[int] = (256, 256, 256),
        activation: str = "elu",
        obs_normalization: bool = False,
        distribution_cfg: dict | None = None,
        preference_group: str = "preference",
        objective_noise_scales: list[float] | None = None,
    ) -> None:
        self.preference_group = preference_group
        super().__init__(obs, obs_groups, obs_set, output_dim, hidden_dims, activation, obs_normalization,
                         distribution_cfg)
        # not persistent: checkpoints load with or without it
        self.register_buffer("noise_scales", self._check_noise_scales(objective_noise_scales), persistent=False)

    def _check_noise_scales(self, scales: list[float] | None) -> torch.Tensor | None:
        """Training's action noise at lambda is the distribution's std times lambda . scales: one factor per
        objective, so exploration can be quieter at one end of the simplex than at another. None: the same noise
        at every lambda (rsl-rl's behaviour)."""
        if scales is None:
            return None
        scales = [float(s) for s in scales]
        if len(scales) != self.preference_dim or min(scales) <= 0.0:
            raise ValueError(f"objective_noise_scales needs {self.preference_dim} positive factors (one per "
                             f"objective), got {scales}.")
        if self.distribution is None or not hasattr(self.distribution, "scale_std"):
            raise ValueError("objective_noise_scales needs a distribution with scale_std, e.g. "
                             "pchc_rsl.modules.distribution:GaussianDistribution.")
        return torch.tensor(scales)

    def forward(
        self,
        obs: TensorDict,
        masks: torch.Tensor | None = None,
        hidden_state: HiddenState = None,
        stochastic_output: bool = False,
    ) -> torch.Tensor:
        """rsl-rl's forward; a sample's noise is scaled by its preference when objective_noise_scales is set."""
        if not stochastic_output or self.noise_scales is None:
            return super().forward(obs, masks, hidden_state, stochastic_output)
        obs = unpad_trajectories(obs, masks) if masks is not None and not self.is_recurrent else obs
        self.distribution.update(self.mlp(self.get_latent(obs, masks, hidden_state)))
        self.distribution.scale_std((obs[self.preference_group] @ self.noise_scales).unsqueeze(-1))
        return self.distribution.sample()

    def _get_obs_dim(self, obs: TensorDict, obs_groups: dict[str, list[str]], obs_set: str) -> tuple[list[str], int]:
        groups = obs_groups[obs_set]
        if self.preference_group not in groups:
            raise ValueError(
                f"{type(self).__name__} needs the preference group '{self.preference_group}' in obs_groups"
                f"['{obs_set}'], got {groups}; e.g. obs_groups = {{'{obs_set}': ['policy', '{self.preference_group}']}}."
            )
        self.preference_dim = obs[self.preference_group].shape[-1]
        active, obs_dim = super()._get_obs_dim(
            obs, {obs_set: [g for g in groups if g != self.preference_group]}, obs_set
        )
        return active, obs_dim

    def _get_latent_dim(self) -> int:
        return self.obs_dim + self.preference_dim

    def get_latent(
        self, obs: TensorDict, masks: torch.Tensor | None = None, hidden_state: HiddenState = None
    ) -> torch.Tensor:
        """[N, obs_dim + m]: the normalised observation groups, then the raw preference."""
        return torch.cat([super().get_latent(obs, masks, hidden_state), obs[self.preference_group]], dim=-1)

    def _head_output_dim(self) -> int:
        """Width of the head output: what the distribution consumes, or output_dim without one."""
        dim = self.distribution.input_dim if self.distribution is not None else self.mlp[-1].out_features
        if not isinstance(dim, int):
            raise ValueError(
                f"{type(self).__name__} supports distributions with a flat parameter vector (e.g. "
                f"GaussianDistribution), got {type(self.distribution).__name__} with input_dim {dim}."
            )
        return dim

    def as_onnx(self, verbose: bool = False) -> nn.Module:
        """A deterministic two-input (obs, preference) copy for ONNX export."""
        return PreferencePolicyExport(self)

    def as_jit(self) -> nn.Module:
        return PreferencePolicyExport(self)


class PreferencePolicyExport(nn.Module):
    """Deterministic inference copy of a PreferenceMLPModel: actions = head([normalise(obs), preference])."""

    is_recurrent: bool = False
    input_names = ["obs", "preference"]
    output_names = ["actions"]

    def __init__(self, model: PreferenceMLPModel) -> None:
        super().__init__()
        self.obs_normalizer = copy.deepcopy(model.obs_normalizer)
        self.mlp = copy.deepcopy(model.mlp)
        if model.distribution is not None:
            self.deterministic_output = model.distribution.as_deterministic_output_module()
        else:
            self.deterministic_output = nn.Identity()
        self.obs_dim = model.obs_dim
        self.preference_dim = model.preference_dim

    def forward(self, obs: torch.Tensor, preference: torch.Tensor) -> torch.Tensor:
        x = torch.cat([self.obs_normalizer(obs), preference], dim=-1)
        return self.deterministic_output(self.mlp(x))

    def get_dummy_inputs(self) -> tuple[torch.Tensor, torch.Tensor]:
        return torch.zeros(2, self.obs_dim), torch.full((2, self.preference_dim), 1.0 / self.preference_dim)


class BatchedExperts(nn.Module):
    """E independent MLPs with their weights stacked per layer: [N, in] -> [E, N, out].

    Evaluated expert by expert (one addmm per layer and expert): on CPUs, E matrix products of the whole batch train
    faster than one batched product (tools/benchmarks/bench_experts.py: 0.70-0.74 of its time for a G1 mini-batch), same
    result. Each expert is initialised like nn.Linear (uniform in +-1/sqrt(fan_in)).
    """

    def __init__(self, num_experts: int, input_dim: int, output_dim: int, hidden_dims, activation: str) -> None:
        super().__init__()
        dims = [input_dim, *hidden_dims, output_dim]
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for fan_in, fan_out in zip(dims[:-1], dims[1:]):
            bound = 1.0 / math.sqrt(fan_in)
            self.weights.append(nn.Parameter(torch.empty(num_experts, fan_in, fan_out).uniform_(-bound, bound)))
            self.biases.append(nn.Parameter(torch.empty(num_experts, 1, fan_out).uniform_(-bound, bound)))
        self.activation = resolve_nn_activation(activation)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        outputs = []
        for e in range(self.weights[0].shape[0]):
            h = torch.addmm(self.biases[0][e], x, self.weights[0][e])
            for weight, bias in zip(self.weights[1:], self.biases[1:]):
                h = torch.addmm(bias[e], self.activation(h), weight[e])
            outputs.append(h)
        return torch.stack(outputs)


class HistoryExpertsHead(nn.Module):
    """Shared body of the mixture heads: encode the history frames, run the experts on [current, lambda, latent].

    The history group is laid out newest first, [s_t, s_{t-1}, ..., s_{t-H}], each frame of equal width; it sits at
    columns [start, stop) of the normalised observation. Everything outside the past frames (the current frame and
    any other group) is the experts' "current observation". The paper concatenates lambda with the observation, so
    by default every expert sees it and can act differently between expert positions; with
    ``experts_see_preference=False`` the experts are preference-blind and lambda acts only through the routing.
    """

    def __init__(self, obs_dim: int, history: tuple[int, int, int], output_dim: int, num_experts: int,
                 expert_hidden_dims, encoder_hidden_dims, latent_dim: int, activation: str, preference_dim: int,
                 experts_see_preference: bool = True) -> None:
        super().__init__()
        self.experts_see_preference = experts_see_preference
        start, stop, history_length = history
        frame_dim = (stop - start) // (history_length + 1)
        self.obs_dim = obs_dim
        self.past_start, self.past_stop = start + frame_dim, stop
        past_dim = self.past_stop - self.past_start
        self.encoder = MLP(past_dim, latent_dim, encoder_hidden_dims, activation) if past_dim > 0 else None
        current_dim = obs_dim - past_dim + (latent_dim if past_dim > 0 else 0)
        current_dim += preference_dim if experts_see_preference else 0
        self.features_dim = current_dim
        self.experts = BatchedExperts(num_experts, current_dim, output_dim, expert_hidden_dims, activation)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """[N, obs_dim + m] -> [N, features]: current observation, lambda (unless blind) and history latent."""
        parts = [x[:, : self.past_start], x[:, self.past_stop : self.obs_dim]]
        if self.experts_see_preference:
            parts.append(x[:, self.obs_dim :])
        if self.encoder is not None:
            parts.append(self.encoder(x[:, self.past_start : self.past_stop]))
        return torch.cat(parts, dim=-1)

    def mix(self, features: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
        """Weighted sum of the expert outputs: weights [N, E] -> [N, out]."""
        return torch.einsum("ne,eno->no", weights, self.experts(features))


class PCIHead(HistoryExpertsHead):
    """Experts routed by routing_weights(lambda): no learned gate, the preference alone decides the mixture (the
    paper). Options that keep the lambda-routed experts and change what they share (docs/results/mo_study.md,
    "Why PCI's runs split"):

    - ``residual``: a shared network that every sample trains, the experts as lambda-routed corrections on it,
      each zero at the start (mu = f(x) + sum_j w_j(lambda) r_j(x), a mixture of residual experts as in MoRE);
    - ``floor``: every expert gets at least this weight, w'_j = floor + (1 - E floor) w_j;
    - ``gate_hidden_dims``: a learned gate on top of the Beta density, w = softmax(log w(lambda) + g(x, lambda)),
      g's last layer zero at the start, so training starts as exact PCI;
    - ``warmup_updates``: the routing scale grows from 0 (every expert alike) to ``scale`` over this many PPO
      updates (``advance_schedule``, called once per update by MultiCriticPPO).
    """

    def __init__(self, positions: torch.Tensor, alpha0: float, beta0: float | None, scale: float,
                 residual: bool = False, floor: float = 0.0, gate_hidden_dims: list[int] | None = None,
                 warmup_updates: int = 0, **kwargs) -> None:
        super().__init__(num_experts=len(positions), **kwargs)
        num_experts = len(positions)
        if not 0.0 <= floor < 1.0 / num_experts:
            raise ValueError(f"routing_floor {floor} must be in [0, 1/{num_experts}) for {num_experts} experts.")
        if warmup_updates < 0:
            raise ValueError(f"routing_warmup_updates must be >= 0, got {warmup_updates}.")
        self.register_buffer("positions", positions)  # [E, m] points on the simplex
        self.alpha0, self.beta0, self.scale = alpha0, beta0, scale
        self.floor, self.warmup_updates = floor, warmup_updates
        if warmup_updates > 0:  # saved with the actor, so a resumed run's warm-up goes on where it was
            self.register_buffer("updates", torch.zeros((), dtype=torch.long))
        out = self.experts.weights[-1].shape[-1]
        self.shared = None
        if residual:
            hidden = [w.shape[-1] for w in self.experts.weights[:-1]]
            self.shared = BatchedExperts(1, self.features_dim, out, hidden, kwargs["activation"])
            with torch.no_grad():
                self.experts.weights[-1].zero_()
                self.experts.biases[-1].zero_()
        self.gate = None
        if gate_hidden_dims is not None:
            self.gate = MLP(self.features_dim, num_experts, list(gate_hidden_dims), kwargs["activation"])
            with torch.no_grad():
                self.gate[-1].weight.zero_()
                self.gate[-1].bias.zero_()

    def current_scale(self) -> float | torch.Tensor:
        """s now: ``scale``, or during the warm-up its share of it (PPO updates so far / warmup_updates)."""
        if self.warmup_updates == 0:
            return self.scale
        return self.scale * (self.updates.float() / self.warmup_updates).clamp(max=1.0)

    def advance_schedule(self) -> None:
        """One PPO update done (the warm-up's clock)."""
        if self.warmup_updates > 0:
            self.updates += 1

    def preference_routing(self, preference: torch.Tensor) -> torch.Tensor:
        """[N, E] the routing lambda alone decides (the Beta density, its warm-up and floor), without a gate."""
        weights = routing_weights(preference, self.positions, self.alpha0, self.beta0, self.current_scale())
        if self.floor > 0.0:
            weights = self.floor + (1.0 - self.positions.shape[0] * self.floor) * weights
        return weights

    def routing(self, x: torch.Tensor, features: torch.Tensor | None = None) -> torch.Tensor:
        """[N, E] expert weights: the preference's density at the expert positions (and the gate's correction)."""
        weights = self.preference_routing(x[:, self.obs_dim :])
        if self.gate is None:
            return weights
        features = self.features(x) if features is None else features
        return torch.softmax(weights.clamp(min=1e-30).log() + self.gate(features), dim=-1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        features = self.features(x)
        mixed = self.mix(features, self.routing(x, features))
        return mixed if self.shared is None else mixed + self.shared(features)[0]


class GatedHead(HistoryExpertsHead):
    """Experts routed by a learned softmax gate over [features, lambda] (the paper's "w/o PCI" ablation)."""

    def __init__(self, gate_hidden_dims, **kwargs) -> None:
        super().__init__(**kwargs)
        num_experts = self.experts.weights[0].shape[0]
        gate_dim = self.features_dim + (0 if self.experts_see_preference else kwargs["preference_dim"])
        self.gate = MLP(gate_dim, num_experts, gate_hidden_dims, kwargs["activation"])

    def routing(self, x: torch.Tensor, features: torch.Tensor | None = None) -> torch.Tensor:
        """[N, E] expert weights: the learned gate's softmax."""
        features = self.features(x) if features is None else features
        gate_input = features if self.experts_see_preference else torch.cat([features, x[:, self.obs_dim :]], dim=-1)
        return torch.softmax(self.gate(gate_input), dim=-1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        features = self.features(x)
        return self.mix(features, self.routing(x, features))


class _MixtureActor(PreferenceMLPModel):
    """Common constructor of the mixture actors: locate the history frames, then build the head."""

    def __init__(
        self,
        obs: TensorDict,
        obs_groups: dict[str, list[str]],
        obs_set: str,
        output_dim: int,
        hidden_dims: tuple[int, ...] | list[int] = (256, 128),
        activation: str = "elu",
        obs_normalization: bool = False,
        distribution_cfg: dict | None = None,
        preference_group: str = "preference",
        history_group: str = "policy",
        history_length: int = 5,
        encoder_hidden_dims: tuple[int, ...] | list[int] = (128,),
        history_latent_dim: int = 32,
        experts_see_preference: bool = True,
        objective_noise_scales: list[float] | None = None,
        trained_experts: list[int] | None = None,
    ) -> None:
        # The base builds a throwaway MLP of hidden_dims; keep it tiny, the experts get hidden_dims below.
        super().__init__(obs, obs_groups, obs_set, output_dim, [1], activation, obs_normalization,
                         distribution_cfg, preference_group, objective_noise_scales)
        self.trained_experts = None if trained_experts is None else list(trained_experts)
        self.head_kwargs = dict(
            obs_dim=self.obs_dim,
            history=self._locate_history(obs, history_group, history_length),
            output_dim=self._head_output_dim(),
            expert_hidden_dims=list(hidden_dims),
            encoder_hidden_dims=list(encoder_hidden_dims),
            latent_dim=history_latent_dim,
            activation=activation,
            preference_dim=self.preference_dim,
            experts_see_preference=experts_see_preference,
        )

    def expert_weights(self, obs: TensorDict) -> torch.Tensor:
        """[N, E] each expert's weight in the actions for these observations: how the mixture shares out the samples
        its experts train on (PCI: fixed by lambda; gated: whatever the gate learned)."""
        return self.mlp.routing(self.get_latent(obs))

    def update_normalization(self, obs: TensorDict) -> None:
        if self.trained_experts is None:  # fine-tuning some experts keeps what the others were trained on
            super().update_normalization(obs)

    def _freeze_all_but_trained_experts(self) -> None:
        """With ``trained_experts``, train only those experts (indices into the experts, as ``positions`` orders
        them): every other parameter (the encoder, the other experts, a gate, the action noise) gets no gradient and
        the observation normaliser keeps its statistics. Fine-tuning the experts at one end of the simplex then leaves
        the preferences the others serve acting as before, as far as the routing gives the trained ones no weight
        there. Start such a run with a fresh optimiser (``pchc-train --init-from``): Adam's momentum from a run that
        trained every expert would go on moving the frozen ones."""
        if self.trained_experts is None:
            return
        num_experts = self.mlp.experts.weights[0].shape[0]
        chosen = self.trained_experts
        if not chosen or len(set(chosen)) != len(chosen) or not all(0 <= e < num_experts for e in chosen):
            raise ValueError(f"trained_experts {chosen}: give distinct expert indices in 0..{num_experts - 1}.")
        mask = torch.zeros(num_experts)
        mask[chosen] = 1.0
        # a buffer, so that it moves with the actor and the gradient hooks never copy it to the device
        self.register_buffer("trained_expert_mask", mask, persistent=False)
        expert_parameters = {id(p) for p in self.mlp.experts.parameters()}
        for parameter in self.parameters():
            if id(parameter) not in expert_parameters:
                parameter.requires_grad_(False)
        self._mask_untrained_expert_gradients()

    def _mask_untrained_expert_gradients(self) -> None:
        """Zero the untrained experts' slices of every batched expert tensor's gradient, with this actor's mask."""
        for parameter in self.mlp.experts.parameters():
            shape = (-1,) + (1,) * (parameter.dim() - 1)
            parameter.register_hook(lambda grad, shape=shape: grad * self.trained_expert_mask.view(shape))

    def __deepcopy__(self, memo: dict) -> _MixtureActor:
        """A copy masks its own gradients: a deep copy of a parameter drops its hooks, and would train every
        expert."""
        copied = self.__class__.__new__(self.__class__)
        memo[id(self)] = copied
        copied.__dict__.update(copy.deepcopy(self.__dict__, memo))
        if copied.trained_experts is not None:
            copied._mask_untrained_expert_gradients()
        return copied

    def _locate_history(self, obs: TensorDict, group: str, history_length: int) -> tuple[int, int, int]:
        """Columns [start, stop) of the history group in the concatenated observation, and H."""
        if group not in self.obs_groups:
            raise ValueError(f"history_group '{group}' is not among the model's groups {self.obs_groups}.")
        start = 0
        for g in self.obs_groups:
            if g == group:
                break
            start += obs[g].shape[-1]
        width = obs[group].shape[-1]
        if history_length < 0 or width % (history_length + 1) != 0:
            raise ValueError(
                f"Group '{group}' has {width} columns, not a multiple of history_length + 1 = {history_length + 1} "
                "frames; set history_length to the number of past frames the environment stacks."
            )
        return start, start + width, history_length


class PCIActor(_MixtureActor):
    """The PCI actor: N_B experts at fixed simplex positions, mixed by the preference-parameterised density.

    hidden_dims are each expert's hidden layers; each expert gets [current observation, lambda, history latent] (the
    paper's design; ``experts_see_preference=False`` for preference-blind experts). ``num_experts`` experts sit on
    the simplex lattice of resolution num_experts - 1 for two objectives (0, .25, .5, .75, 1 by default); for m
    objectives the default lattice of resolution ``lattice_resolution`` is used, or pass ``expert_positions`` ([E]
    for m = 2, else [E, m]). ``residual_experts``, ``routing_floor``, ``prior_gate_hidden_dims`` and
    ``routing_warmup_updates`` are PCIHead's options (off by default: the paper's routing).
    """

    def __init__(
        self,
        obs: TensorDict,
        obs_groups: dict[str, list[str]],
        obs_set: str,
        output_dim: int,
        num_experts: int = 5,
        expert_positions: list | None = None,
        lattice_resolution: int = 2,
        alpha0: float = 1.0,
        beta0: float | None = None,
        routing_scale: float = DEFAULT_ROUTING_SCALE,
        residual_experts: bool = False,
        routing_floor: float = 0.0,
        prior_gate_hidden_dims: list[int] | None = None,
        routing_warmup_updates: int = 0,
        **kwargs,
    ) -> None:
        super().__init__(obs, obs_groups, obs_set, output_dim, **kwargs)
        m = self.preference_dim
        if expert_positions is not None:
            positions = expert_positions_on_simplex(expert_positions, m)
        elif m == 2:
            positions = simplex_lattice(2, num_experts - 1)
        else:
            positions = simplex_lattice(m, lattice_resolution)
        self.mlp = PCIHead(positions, alpha0, beta0, routing_scale, residual=residual_experts, floor=routing_floor,
                           gate_hidden_dims=prior_gate_hidden_dims, warmup_updates=routing_warmup_updates,
                           **self.head_kwargs)
        self._freeze_all_but_trained_experts()

    def expert_weights(self, obs: TensorDict) -> torch.Tensor:
        """[N, E]: without a gate PCI's weights depend on lambda alone, so the observation is not encoded."""
        if self.mlp.gate is not None:
            return super().expert_weights(obs)
        return self.mlp.preference_routing(obs[self.preference_group])

    def advance_schedule(self) -> None:
        """Called once per PPO update (MultiCriticPPO): the routing warm-up's clock."""
        self.mlp.advance_schedule()


class GatedMoEActor(_MixtureActor):
    """The "w/o PCI" ablation: the PCI actor's experts routed by a learned gate instead of the Beta density."""

    def __init__(
        self,
        obs: TensorDict,
        obs_groups: dict[str, list[str]],
        obs_set: str,
        output_dim: int,
        num_experts: int = 5,
        gate_hidden_dims: tuple[int, ...] | list[int] = (64,),
        **kwargs,
    ) -> None:
        super().__init__(obs, obs_groups, obs_set, output_dim, **kwargs)
        self.mlp = GatedHead(list(gate_hidden_dims), num_experts=num_experts, **self.head_kwargs)
        self._freeze_all_but_trained_experts()
