"""MultiCriticPPO: PPO with a task critic and one critic per objective, advantages combined by the preference."""

from __future__ import annotations

import torch
from tensordict import TensorDict

from rsl_rl.algorithms import PPO
from rsl_rl.env import VecEnv
from rsl_rl.extensions import resolve_rnd_config, resolve_symmetry_config
from rsl_rl.models import MLPModel
from rsl_rl.modules import EmpiricalNormalization
from rsl_rl.utils import reduce_gradients_in_buckets, resolve_class, resolve_obs_groups

from pchc_rsl.algorithms.mirror_loss import SharedPassSymmetry
from pchc_rsl.amp.style import AMPStyle
from pchc_rsl.storage import MultiCriticRolloutStorage


class MultiCriticPPO(PPO):
    """PPO with K = 1 + m value heads trained on ``extras["reward_groups"]`` ([N, K]: task, obj_1 .. obj_m).

    Each critic gets its own GAE (with its own time-out bootstrap); each advantage is normalised over the
    rollout, and the policy is trained on (the paper's Eq. for A^lambda)
        A = w_task A_task + sum_i lambda_i A_obj_i,
    with lambda read from the stored preference observation of each transition and w_task = 1 in the paper.
    Normalisation erases each group's reward scale, so w_task (as HoST's per-critic coefficients) is the only way to
    say how much the task matters against the objectives.

    Two safeguards make it work on environments written without it in mind:
    - A silent group contributes nothing: a group whose reward was the same constant at every step of the rollout
      carries no information about the actions (zero, or constant with only time-outs ending episodes), and
      normalising its advantage would blow value-estimation noise up to unit scale. Its advantage is set to 0.
    - Value normalisation (``value_normalization=True``): each value head predicts its return in units of a running
      mean and std of that critic's returns, so value clipping (``clip_param``) and the value loss (averaged over
      the critics) are scale-free whatever each group's reward scale. GAE and time-out bootstraps use raw values.
    Use it from any rsl-rl config: ``"algorithm": {"class_name": "pchc_rsl.algorithms:MultiCriticPPO", ...}``.
    """

    def __init__(
        self,
        actor: MLPModel,
        critic: MLPModel,
        storage: MultiCriticRolloutStorage,
        preference_group: str = "preference",
        reward_group_names: list[str] | None = None,
        task_advantage_weight: float = 1.0,
        value_normalization: bool = True,
        amp_cfg: dict | None = None,
        **kwargs,
    ) -> None:
        if kwargs.get("normalize_advantage_per_mini_batch"):
            raise ValueError(
                "MultiCriticPPO normalises each critic's advantage over the rollout before weighting them by "
                "lambda; normalize_advantage_per_mini_batch=True would rescale the weighted sum. Set it to False."
            )
        super().__init__(actor, critic, storage, **kwargs)
        if self.symmetry is not None:  # the same mirror loss, without a second actor pass per mini-batch
            self.symmetry = SharedPassSymmetry(**kwargs["symmetry_cfg"])
        self.preference_group = preference_group
        self.task_advantage_weight = task_advantage_weight
        self.num_critics = storage.num_critics
        self.reward_group_names = reward_group_names or ["task"] + [f"obj_{i}" for i in range(1, self.num_critics)]
        if len(self.reward_group_names) != self.num_critics:
            raise ValueError(
                f"reward_group_names {self.reward_group_names} must name all {self.num_critics} critics "
                "(task first, then one per objective)."
            )
        self.return_stats: dict[str, float] = {}
        # Running per-critic return statistics; values are predicted in their units (identity when disabled).
        self.value_normalizer = (
            EmpiricalNormalization(self.num_critics).to(self.device) if value_normalization else None
        )
        self._reset_group_activity()
        self.amp = AMPStyle(device=self.device, **amp_cfg) if amp_cfg else None

    def _reset_group_activity(self) -> None:
        """Per-rollout record of each group's reward range and of terminations (what ``silent_groups`` needs)."""
        self.group_min = torch.full((self.num_critics,), float("inf"), device=self.device)
        self.group_max = torch.full((self.num_critics,), float("-inf"), device=self.device)
        self.terminated_in_rollout = torch.zeros((), dtype=torch.bool, device=self.device)
        """Whether an episode terminated (not timed out) in this rollout: on the device, read once per rollout."""

    def silent_groups(self) -> torch.Tensor:
        """[K] bool: groups whose reward said nothing about the actions in this rollout.

        A reward that was one constant c at every step is silent when c = 0 (every return is 0) or when no episode
        terminated (time-outs are bootstrapped, so every return is c / (1 - gamma)); a nonzero constant with
        terminations is a survival signal and is kept.
        """
        low, high = self.group_min.clone(), self.group_max.clone()
        terminated = self.terminated_in_rollout.float()
        if self.is_multi_gpu:  # every rank must drop the same groups, or their averaged gradients mix objectives
            torch.distributed.all_reduce(low, op=torch.distributed.ReduceOp.MIN)
            torch.distributed.all_reduce(high, op=torch.distributed.ReduceOp.MAX)
            torch.distributed.all_reduce(terminated, op=torch.distributed.ReduceOp.MAX)
        span = high - low  # inf before the first recorded step: nothing is silent then
        scale = torch.maximum(high.abs(), low.abs()).clamp(min=1.0)
        constant = torch.isfinite(span) & (span <= 1e-6 * scale)
        zero = high.abs() <= 1e-12
        return constant & (zero | (terminated == 0))

    def act(self, obs: TensorDict) -> torch.Tensor:
        actions = super().act(obs)
        self.transition.values = self._raw_values(self.transition.values)
        return actions

    def _raw_values(self, values: torch.Tensor) -> torch.Tensor:
        """Critic output [.., K] -> values in return units."""
        return values if self.value_normalizer is None else self.value_normalizer.inverse(values)

    def process_env_step(
        self, obs: TensorDict, rewards: torch.Tensor, dones: torch.Tensor, extras: dict
    ) -> None:
        """Record one step; the per-critic rewards come from extras["reward_groups"], ``rewards`` is only logged."""
        if "reward_groups" not in extras:
            raise KeyError("MultiCriticPPO needs extras['reward_groups'] ([N, 1 + m]: task, then each objective).")
        groups = extras["reward_groups"].to(self.device)
        if groups.shape != (rewards.shape[0], self.num_critics):
            raise ValueError(
                f"extras['reward_groups'] has shape {list(groups.shape)}; expected [{rewards.shape[0]}, "
                f"{self.num_critics}] (task + {self.num_critics - 1} objectives, as many as the preference has)."
            )
        self.transition.rewards = groups.clone()
        if self.amp is not None:
            # style is preference-invariant: task group. On a terminal step obs already holds the next episode's
            # first window; an env that provides extras["amp_observations"] gives the window that was just lived.
            windows = extras.get("amp_observations", obs[self.amp.obs_group])
            self.transition.rewards[:, 0] += self.amp.reward(windows.to(self.device)).to(self.device)
        self.transition.dones = dones
        if self.rnd:
            self.intrinsic_rewards = self.rnd.get_intrinsic_reward(obs)
            self.transition.rewards[:, 0] += self.intrinsic_rewards  # curiosity is preference-invariant: task group
        self.group_min = torch.minimum(self.group_min, self.transition.rewards.amin(dim=0))
        self.group_max = torch.maximum(self.group_max, self.transition.rewards.amax(dim=0))
        no_time_outs = torch.zeros_like(dones, dtype=torch.bool)
        time_outs = extras["time_outs"].to(self.device).bool() if "time_outs" in extras else no_time_outs
        self.terminated_in_rollout |= (dones.bool() & ~time_outs.view_as(dones)).any()
        # Bootstrapping on time-outs, per critic: r_k += gamma * V_k(s_T)
        if "time_outs" in extras:
            self.transition.rewards += self.gamma * self.transition.values * time_outs.unsqueeze(1).float()
        self.storage.add_transition(self.transition)
        self.transition.clear()
        self.actor.reset(dones)
        self.critic.reset(dones)

    def compute_returns(self, obs: TensorDict) -> None:
        """Per-critic GAE, per-critic normalisation, then the preference-weighted sum."""
        st = self.storage
        critic_hidden_state = self.critic.get_hidden_state()
        last_values = self._raw_values(self.critic(obs).detach())
        self.critic.reset(hidden_state=critic_hidden_state)
        advantage = torch.zeros_like(last_values)  # [N, K]
        for step in reversed(range(st.num_transitions_per_env)):
            next_values = last_values if step == st.num_transitions_per_env - 1 else st.values[step + 1]
            next_is_not_terminal = 1.0 - st.dones[step].float()  # [N, 1], broadcast over the K critics
            # delta_k = r_k + gamma V_k(s') - V_k(s);  A_k = delta_k + gamma lam A_k(s')
            delta = st.rewards[step] + next_is_not_terminal * self.gamma * next_values - st.values[step]
            advantage = delta + next_is_not_terminal * self.gamma * self.lam * advantage
            st.returns[step] = advantage + st.values[step]
        advantages = st.returns - st.values  # [T, N, K]
        # Normalise each critic's advantage over the rollout: A_k <- (A_k - mean_k) / std_k
        flat = advantages.flatten(0, 1)
        mean, std = flat.mean(dim=0), flat.std(dim=0)
        normalised = (advantages - mean) / (std + 1e-8)
        silent = self.silent_groups_last = self.silent_groups()
        normalised = torch.where(silent, torch.zeros_like(normalised), normalised)
        # A^lambda = w_task A_task + sum_i lambda_i A_obj_i
        lam = st.observations[self.preference_group].to(normalised.dtype)  # [T, N, m]
        st.advantages = self.task_advantage_weight * normalised[..., :1] + (lam * normalised[..., 1:]).sum(
            dim=-1, keepdim=True
        )
        self._record_return_stats(flat, std, silent)
        self._record_routing_mass()
        self._reset_group_activity()
        if self.value_normalizer is not None:
            # The value loss compares critic outputs with returns in the normalised units of the updated statistics.
            self.value_normalizer.update(st.returns.flatten(0, 1))
            st.values = self.value_normalizer(st.values)
            st.returns = self.value_normalizer(st.returns)

    def _record_return_stats(self, advantages: torch.Tensor, adv_std: torch.Tensor, silent: torch.Tensor) -> None:
        """Per-critic value error of the rollout's critic (mean squared raw advantage, returns - values) and raw
        advantage spread, logged with the losses. advantages: [T * N, K]."""
        value_error = advantages.pow(2).mean(dim=0)
        self.return_stats = {}
        for k, name in enumerate(self.reward_group_names):
            self.return_stats[f"value_error/{name}"] = value_error[k].item()
            self.return_stats[f"advantage_std/{name}"] = adv_std[k].item()
            self.return_stats[f"silent_group/{name}"] = float(silent[k])

    def _record_routing_mass(self) -> None:
        """Each expert's mean weight over the rollout's states (``routing_mass/expert_<j>``, logged with the losses):
        its share of the samples, which is what it trains on. Mixture actors only (those with ``expert_weights``)."""
        if not hasattr(self.actor, "expert_weights"):
            return
        states = self.storage.observations.flatten(0, 1)  # views, no copy
        with torch.no_grad():  # in chunks: a G1 rollout is ~10^5 states
            mass = sum(self.actor.expert_weights(states[i : i + 16384]).sum(dim=0)
                       for i in range(0, states.shape[0], 16384)) / states.shape[0]
        for j, value in enumerate(mass.tolist()):
            self.return_stats[f"routing_mass/expert_{j}"] = value

    def update(self) -> dict[str, float]:
        loss_dict = super().update()
        loss_dict.update(self.return_stats)
        if hasattr(self.actor, "advance_schedule"):  # e.g. the PCI actor's routing warm-up
            self.actor.advance_schedule()
        if self.amp is not None:
            reduce = self._reduce_amp_gradients if self.is_multi_gpu else None
            loss_dict.update(self.amp.update(reduce))
        return loss_dict

    def _reduce_amp_gradients(self, params) -> None:
        reduce_gradients_in_buckets(params, self.gpu_world_size, self.grad_reduce_bucket_mb)

    def save(self) -> dict:
        saved = super().save()
        if self.amp is not None:
            saved["amp_state_dict"] = self.amp.state_dict()
        if self.value_normalizer is not None:
            saved["value_normalizer_state_dict"] = self.value_normalizer.state_dict()
        return saved

    def load(self, loaded_dict: dict, load_cfg: dict | None, strict: bool) -> bool:
        if "optimizer_state_dict" not in loaded_dict:  # a released policy: training continues with a fresh optimizer
            defaults = {"actor": True, "critic": True, "optimizer": True, "iteration": True, "rnd": True}
            load_cfg = {**(load_cfg or defaults), "optimizer": False}
        load_iteration = super().load(loaded_dict, load_cfg, strict)
        if self.amp is not None and "amp_state_dict" in loaded_dict and (load_cfg is None or load_cfg.get("amp", True)):
            saved_width = loaded_dict["amp_state_dict"]["discriminator"].get("normalizer._mean")
            width = self.amp.replay.dim
            if saved_width is not None and saved_width.shape[-1] != width:
                raise ValueError(f"the checkpoint's discriminator reads {saved_width.shape[-1]} AMP inputs, this run's "
                                 f"{width} (amp_window, amp_root_velocity): start it with --fresh-discriminator.")
            self.amp.load_state_dict(loaded_dict["amp_state_dict"])
        if self.value_normalizer is not None and "value_normalizer_state_dict" in loaded_dict and (
            load_cfg is None or load_cfg.get("critic", True)
        ):
            self.value_normalizer.load_state_dict(loaded_dict["value_normalizer_state_dict"])
        return load_iteration

    def broadcast_parameters(self) -> None:
        super().broadcast_parameters()
        if self.value_normalizer is not None:
            for tensor in self.value_normalizer.state_dict().values():
                torch.distributed.broadcast(tensor, src=0)
        if self.amp is not None:
            for tensor in self.amp.discriminator.state_dict().values():
                torch.distributed.broadcast(tensor, src=0)

    @staticmethod
    def resolve_amp_config(amp_cfg: dict | None, obs: TensorDict, env: VecEnv) -> dict | None:
        """Fill the AMP input width, the motion frame rate (the policy rate) and, from an env that tells them
        (``joint_ranges(names)``, ``amp_root_velocity``), the robot's joint ranges the clips must respect and whether
        its amp frames hold the root's velocity; None (with a note) without motions. Public so that tools rebuild the
        style reward exactly as training does (tools/diagnostics/style_score.py)."""
        if not amp_cfg:
            return None
        amp_cfg = dict(amp_cfg)
        if not amp_cfg.get("motion_files"):
            print("AMP is off: no motion files given (pchc-train --motion-files PATH, e.g. a LAFAN1 G1 folder).")
            return None
        group = amp_cfg.get("obs_group", "amp")
        if group not in obs:
            raise ValueError(f"AMP reads the '{group}' observation group, which the environment does not provide.")
        amp_cfg["input_dim"] = obs[group].shape[-1]
        if "fps" not in amp_cfg:
            if not hasattr(env, "dt"):
                raise ValueError("AMP needs amp_cfg['fps'] (the policy rate) or an env with a 'dt' attribute.")
            amp_cfg["fps"] = 1.0 / env.dt
        if "joint_ranges" not in amp_cfg and hasattr(env, "joint_ranges"):
            amp_cfg["joint_ranges"] = env.joint_ranges(amp_cfg["joint_names"])
        if amp_cfg.get("root_velocity") is None:
            amp_cfg["root_velocity"] = bool(getattr(env, "amp_root_velocity", False))
        return amp_cfg

    @staticmethod
    def construct_algorithm(obs: TensorDict, env: VecEnv, cfg: dict, device: str) -> MultiCriticPPO:
        """Build actor, a critic with 1 + m outputs, the multi-critic storage and the algorithm.

        Differs from PPO.construct_algorithm only in the critic width and the storage.
        """
        alg_class, alg_cfg = resolve_class(cfg["algorithm"])
        actor_class, actor_cfg = resolve_class(cfg["actor"])
        critic_class, critic_cfg = resolve_class(cfg["critic"])
        default_sets = ["actor", "critic"]
        if alg_cfg.get("rnd_cfg") is not None:
            default_sets.append("rnd_state")
        cfg["obs_groups"] = resolve_obs_groups(obs, cfg["obs_groups"], default_sets)
        alg_cfg = resolve_rnd_config(alg_cfg, obs, cfg["obs_groups"], env)
        alg_cfg = resolve_symmetry_config(alg_cfg, env)

        preference_group = alg_cfg.get("preference_group", "preference")
        if preference_group not in obs:
            raise ValueError(
                f"MultiCriticPPO reads lambda from the observation group '{preference_group}', which the environment "
                f"does not provide (groups: {list(obs.keys())})."
            )
        num_critics = 1 + obs[preference_group].shape[-1]
        alg_cfg["amp_cfg"] = MultiCriticPPO.resolve_amp_config(alg_cfg.get("amp_cfg"), obs, env)

        actor: MLPModel = actor_class(obs, cfg["obs_groups"], "actor", env.num_actions, **actor_cfg).to(device)
        print(f"Actor Model: {actor}")
        alg_cfg.pop("share_cnn_encoders", None)
        critic: MLPModel = critic_class(obs, cfg["obs_groups"], "critic", num_critics, **critic_cfg).to(device)
        print(f"Critic Model: {critic}")
        storage = MultiCriticRolloutStorage(
            env.num_envs, cfg["num_steps_per_env"], obs, [env.num_actions], num_critics, device
        )
        alg = alg_class(actor, critic, storage, device=device, **alg_cfg, multi_gpu_cfg=cfg["multi_gpu"])
        alg.compile(cfg.get("torch_compile_mode"))
        return alg
