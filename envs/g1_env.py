"""The G1 as an rsl-rl VecEnv: batched C MuJoCo physics, task logic in torch over the whole batch.

A task is a G1EnvConfig: which joints, which reward terms (each tagged with its group: "task" or an objective),
pushes, randomisation and terminations. The env sums each group into ``extras["reward_groups"]`` ([N, 1 + m],
objectives raw) and returns r = r_task + sum_i lambda_i r_obj_i, as DESIGN.md specifies.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
import torch
from tensordict import TensorDict

from rsl_rl.env import VecEnv
from rsl_rl.utils import resolve_callable

from pchc_rsl.envs.physics import BatchedMuJoCo
from pchc_rsl.preference import EnvPreferences
from pchc_rsl.robots.g1.constants import STANDING_HEIGHT
from pchc_rsl.robots.g1.model import build_g1_model, default_joint_positions


@dataclass
class RewardTerm:
    func: str
    """``"module:function"``; called as func(env, **params) -> Tensor[N]."""
    weight: float
    group: str = "task"
    """"task" (preference-invariant) or one of the config's objective names."""
    params: dict = field(default_factory=dict)


@dataclass
class PushConfig:
    """Velocity impulses on the pelvis at random intervals; the window after each is the paper's 'after-disturb'."""

    enabled: bool = True
    interval_s: tuple[float, float] = (3.0, 6.0)
    velocity: tuple[float, float] = (0.3, 1.0)
    """Horizontal speed added to the pelvis, m/s, uniform in this range, in a uniformly random direction."""
    window_s: float = 1.0


PUSH_PRESETS = {
    "mild": PushConfig(interval_s=(3.0, 3.0), velocity=(0.5, 0.5)),
    "strong": PushConfig(interval_s=(3.0, 3.0), velocity=(1.2, 1.2)),
}
"""Evaluation pushes: fixed interval and strength."""


@dataclass
class RandomizationConfig:
    """Per-env physical randomisation, drawn once per env when the env is built (one model copy per env)."""

    enabled: bool = True
    friction: tuple[float, float] = (0.4, 1.2)
    added_base_mass: tuple[float, float] = (-1.0, 3.0)
    actuator_strength: tuple[float, float] = (0.9, 1.1)
    """Scale on kp and kd of every actuator."""


@dataclass
class G1EnvConfig:
    joints: list[str]
    timestep: float = 0.002
    decimation: int = 10
    episode_length_s: float = 10.0
    num_threads: int = 1
    action_scale: float = 0.25
    """eta: q_target = q_default + eta * a."""
    action_clip: float = 10.0
    history_length: int = 5
    amp_window: int = 5
    """Frames of actuated joint positions in the ``amp`` observation group (the AMP state window)."""
    observation_noise: float = 1.0
    """Multiplies the per-quantity noise scales (0 turns noise off)."""
    command_ranges: dict[str, tuple[float, float]] = field(
        default_factory=lambda: {"lin_vel_x": (0.0, 0.0), "lin_vel_y": (0.0, 0.0), "ang_vel_z": (0.0, 0.0)}
    )
    use_command: bool = False
    """Whether the policy observes the velocity command (walking)."""
    initial_joint_noise: float = 0.1
    push: PushConfig = field(default_factory=PushConfig)
    randomization: RandomizationConfig = field(default_factory=RandomizationConfig)
    objective_names: list[str] = field(default_factory=lambda: ["obj_1", "obj_2"])
    rewards: list[RewardTerm] = field(default_factory=list)
    preference_concentration: float = 1.0
    preference_resample_prob: float = 0.0
    """Per-step probability of re-sampling lambda mid-episode."""
    termination_height: float = 0.4
    termination_tilt: float = 0.8
    """Terminate when the horizontal part of gravity in the base frame exceeds this (|g_xy|, g = 1)."""
    contact_force_threshold: float = 1.0


def quat_rotate_inverse(q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Rotate world vectors v [N, 3] into the frame of unit quaternions q [N, 4] (w, x, y, z)."""
    w, xyz = q[:, :1], q[:, 1:]
    t = 2.0 * torch.cross(xyz, v, dim=-1)
    return v - w * t + torch.cross(xyz, t, dim=-1)


def yaw_of(q: torch.Tensor) -> torch.Tensor:
    w, x, y, z = q.unbind(-1)
    return torch.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


GRAVITY_DIRECTION = torch.tensor([0.0, 0.0, -1.0])
NOISE_SCALES = {"ang_vel": 0.2, "gravity": 0.05, "joint_pos": 0.01, "joint_vel": 1.5}


class G1Env(VecEnv):
    """N G1 robots; see G1EnvConfig. Device is the CPU (the physics runs there)."""

    uses_body_forces = False
    """Tasks that push bodies with external forces (e.g. the fall-recovery assist) set this."""

    def __init__(self, cfg: G1EnvConfig, num_envs: int, device: str = "cpu", seed: int = 0) -> None:
        if cfg.preference_concentration <= 0:
            raise ValueError("preference_concentration must be > 0.")
        # the physics runs on the CPU, so the env's tensors live there; the runner moves them to its own device
        self.cfg, self.num_envs, self.device = cfg, num_envs, "cpu"
        self.num_objectives = len(cfg.objective_names)
        self.num_actions = len(cfg.joints)
        self.dt = cfg.timestep * cfg.decimation
        self.max_episode_length = int(math.ceil(cfg.episode_length_s / self.dt))
        self.generator = torch.Generator().manual_seed(seed)
        self.rng = np.random.default_rng(seed)

        model = build_g1_model(cfg.joints, cfg.timestep)
        self.physics = BatchedMuJoCo(self._randomized_models(model), num_envs, cfg.decimation, cfg.num_threads,
                                     with_body_forces=self.uses_body_forces)
        self.model = model
        self._sensor_index = self._sensor_indices()
        self.default_joint_pos = torch.tensor(default_joint_positions(cfg.joints))
        qpos_adr = [model.jnt_qposadr[model.joint(j).id] for j in cfg.joints]
        dof_adr = [model.jnt_dofadr[model.joint(j).id] for j in cfg.joints]
        self.joint_qpos_idx, self.joint_dof_idx = torch.tensor(qpos_adr), torch.tensor(dof_adr)
        ranges = torch.tensor(model.jnt_range[[model.joint(j).id for j in cfg.joints]], dtype=torch.float32)
        self.soft_joint_limits = ranges.mean(-1, keepdim=True) + 0.45 * (ranges[:, 1:] - ranges[:, :1]) * torch.tensor([-1.0, 1.0])
        self.torque_limits = torch.tensor([model.actuator_forcerange[i, 1] for i in range(model.nu)], dtype=torch.float32)

        self.reward_terms = [(resolve_callable(t.func), t) for t in cfg.rewards]
        groups = ["task", *cfg.objective_names]
        for _, term in self.reward_terms:
            if term.group not in groups:
                raise ValueError(f"Reward term {term.func} has group '{term.group}'; allowed: {groups}.")
        self.group_index = {g: i for i, g in enumerate(groups)}

        n, j = num_envs, self.num_actions
        self.actions = torch.zeros(n, j)
        self.last_actions = torch.zeros(n, j)
        self.episode_length_buf = torch.zeros(n, dtype=torch.long)
        self.commands = torch.zeros(n, 3)
        self.preferences = EnvPreferences(n, self.num_objectives, cfg.preference_concentration, self.generator)
        self.preference = self.preferences.values
        self.action_scale = torch.full((n, 1), cfg.action_scale)
        frame_dim = 3 + 3 + 3 * j + 1 + (3 if cfg.use_command else 0)
        self.frames = torch.zeros(n, cfg.history_length + 1, frame_dim)
        self.amp_frames = torch.zeros(n, cfg.amp_window, j)  # oldest first
        # contacts, strides
        self.foot_contact = torch.zeros(n, 2, dtype=torch.bool)
        self.first_contact = torch.zeros(n, 2, dtype=torch.bool)
        self.air_time = torch.zeros(n, 2)
        self.last_air_time = torch.zeros(n, 2)
        self.last_contact_pos = torch.zeros(n, 2, 2)
        self.stride = torch.zeros(n, 2)
        """Horizontal distance from the last contact point at each touchdown this step (0 elsewhere), m."""
        # pushes
        self.push_countdown = torch.zeros(n, dtype=torch.long)
        self.push_window = torch.zeros(n, dtype=torch.long)
        self.push_dir = torch.zeros(n, 2)
        self.push_origin = torch.zeros(n, 2)
        self.push_ref_vel = torch.zeros(n, 2)
        self.push_elapsed = torch.zeros(n)
        self.push_max_deviation = torch.zeros(n)
        # episode statistics
        self.episode_sums = torch.zeros(n, 1 + self.num_objectives)
        self.metric_sums: dict[str, torch.Tensor] = {}
        self.unstable_resets = 0
        self._read_state()
        self._reset(torch.arange(n))

    # ---------------------------------------------------------------- construction
    def _randomized_models(self, model: mujoco.MjModel) -> mujoco.MjModel | list[mujoco.MjModel]:
        r = self.cfg.randomization
        if not r.enabled:
            return model
        models = []
        floor = model.geom("floor").id
        base = model.body("pelvis").id
        for _ in range(self.num_envs):
            m = copy.copy(model)
            m.geom_friction[floor, 0] = self.rng.uniform(*r.friction)
            m.body_mass[base] += self.rng.uniform(*r.added_base_mass)
            strength = self.rng.uniform(*r.actuator_strength)
            m.actuator_gainprm[:, 0] *= strength
            m.actuator_biasprm[:, 1:3] *= strength
            models.append(m)
        return models

    # ---------------------------------------------------------------- state
    def _sensor_indices(self) -> dict[str, torch.Tensor]:
        """Columns of the sensor readings the env reads every step, looked up once by sensor name."""
        p, feet = self.physics, ("left_foot", "right_foot")

        def columns(name: str) -> list[int]:
            cols = p.sensor_columns(name)
            return list(range(cols.start, cols.stop))

        return {
            "foot_pos": torch.tensor([columns(f"{s}_pos") for s in feet]),  # [2, 3]
            "foot_vel": torch.tensor([columns(f"{s}_linvel") for s in feet]),  # [2, 3]
            "foot_touch": torch.tensor([columns(f"{s}_touch")[0] for s in feet]),  # [2]
            "torque": torch.tensor([columns(f"{j}_torque")[0] for j in self.cfg.joints]),  # [J]
        }

    def _read_state(self) -> None:
        """Pull the latest physics state into torch views (zero-copy where possible)."""
        p = self.physics
        qpos, qvel = torch.from_numpy(p.qpos).float(), torch.from_numpy(p.qvel).float()
        self.base_pos = qpos[:, :3]
        self.base_quat = qpos[:, 3:7]
        self.base_lin_vel_w = qvel[:, :3]
        self.base_ang_vel = qvel[:, 3:6]  # free joint: angular velocity in the body frame
        self.base_lin_vel = quat_rotate_inverse(self.base_quat, self.base_lin_vel_w)
        self.projected_gravity = quat_rotate_inverse(self.base_quat, GRAVITY_DIRECTION.expand(self.num_envs, 3))
        self.joint_pos = qpos[:, self.joint_qpos_idx]
        self.joint_vel = qvel[:, self.joint_dof_idx]
        sensors = torch.from_numpy(p.substep_sensors).float()  # [N, K, S]
        index = self._sensor_index
        self.foot_pos = sensors[:, -1, index["foot_pos"]]  # [N, 2, 3]
        self.foot_vel = sensors[:, -1, index["foot_vel"]]
        self.foot_touch_substeps = sensors[:, :, index["foot_touch"]]  # [N, K, 2]
        self.torques_substeps = sensors[:, :, index["torque"]]  # [N, K, J]
        self.joint_vel_substeps = torch.from_numpy(p.substep_states[:, :, p.qvel_slice]).float()[:, :, self.joint_dof_idx]
        self.torques = self.torques_substeps[:, -1]

    def _update_contacts(self) -> None:
        """Touchdowns from the substep contact forces; stride = distance from the last contact point at touchdown."""
        contact = (self.foot_touch_substeps > self.cfg.contact_force_threshold).any(dim=1)
        self.first_contact = contact & ~self.foot_contact
        foot_xy = self.foot_pos[..., :2]
        self.stride = torch.where(self.first_contact, (foot_xy - self.last_contact_pos).norm(dim=-1), 0.0)
        self.last_air_time = torch.where(self.first_contact, self.air_time + self.dt, self.last_air_time)
        self.air_time = torch.where(contact, 0.0, self.air_time + self.dt)
        self.last_contact_pos = torch.where(contact.unsqueeze(-1), foot_xy, self.last_contact_pos)
        self.foot_contact = contact

    # ---------------------------------------------------------------- preference
    def set_preference(self, lam) -> None:
        """Hold lambda ([m] for all envs or [N, m]) from now on, across resets; ``None`` resumes sampling."""
        self.preferences.hold(lam)

    # ---------------------------------------------------------------- reset
    def _uniform(self, n: int, low: float, high: float) -> torch.Tensor:
        return low + (high - low) * torch.rand(n, generator=self.generator)

    def _reset(self, env_ids: torch.Tensor) -> None:
        n = len(env_ids)
        if n == 0:
            return
        qpos, qvel = self.initial_state(env_ids)
        self.physics.set_qpos_qvel(env_ids.numpy(), qpos.double().numpy(), qvel.double().numpy())
        self.physics.substep_sensors[env_ids.numpy()] = 0.0
        self.physics.substep_states[env_ids.numpy()] = self.physics.state[env_ids.numpy()][:, None]
        self._read_state()
        r = self.cfg.command_ranges
        self.commands[env_ids] = torch.stack(
            [self._uniform(n, *r["lin_vel_x"]), self._uniform(n, *r["lin_vel_y"]), self._uniform(n, *r["ang_vel_z"])], 1
        )
        self.preferences.resample(env_ids)
        self.actions[env_ids] = 0.0
        self.last_actions[env_ids] = 0.0
        self.episode_length_buf[env_ids] = 0
        self.foot_contact[env_ids] = False
        self.air_time[env_ids] = 0.0
        self.last_contact_pos[env_ids] = self.foot_pos[env_ids, :, :2]
        self.push_countdown[env_ids] = self._push_interval(n)
        self.push_window[env_ids] = 0
        self.episode_sums[env_ids] = 0.0
        for value in self.metric_sums.values():
            value[env_ids] = 0.0
        frame = self._frame()[env_ids]
        self.frames[env_ids] = frame.unsqueeze(1)
        self.amp_frames[env_ids] = self.joint_pos[env_ids].unsqueeze(1)

    def initial_state(self, env_ids: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Standing at the default pose with joint noise (tasks override for other starts). [n, nq], [n, nv]."""
        n = len(env_ids)
        qpos = torch.zeros(n, self.model.nq)
        qpos[:, 2] = STANDING_HEIGHT
        qpos[:, 3] = 1.0
        noise = self.cfg.initial_joint_noise * (2 * torch.rand(n, self.num_actions, generator=self.generator) - 1)
        qpos[:, self.joint_qpos_idx] = self.default_joint_pos + noise
        return qpos, torch.zeros(n, self.model.nv)

    def _push_interval(self, n: int) -> torch.Tensor:
        low, high = self.cfg.push.interval_s
        return (self._uniform(n, low, high) / self.dt).long().clamp(min=1)

    # ---------------------------------------------------------------- pushes
    def _apply_pushes(self) -> None:
        """Add a horizontal velocity impulse to the pelvis of envs whose countdown ran out; record d and x_last."""
        if not self.cfg.push.enabled:
            return
        self.push_countdown -= 1
        ids = (self.push_countdown <= 0).nonzero(as_tuple=False).squeeze(-1)
        if len(ids) == 0:
            return
        n = len(ids)
        angle = self._uniform(n, 0.0, 2 * math.pi)
        direction = torch.stack([angle.cos(), angle.sin()], -1)
        speed = self._uniform(n, *self.cfg.push.velocity)
        qvel = self.physics.state[:, self.physics.qvel_slice]
        qvel[ids.numpy(), :2] += (speed.unsqueeze(-1) * direction).double().numpy()
        self.physics.state[:, self.physics.qvel_slice] = qvel
        self.push_dir[ids] = direction
        self.push_origin[ids] = self.base_pos[ids, :2]
        # where the base should go meanwhile: the commanded velocity, turned into the world by the heading at the push
        yaw = yaw_of(self.base_quat[ids])
        cmd = self.commands[ids, :2]
        self.push_ref_vel[ids] = torch.stack(
            [yaw.cos() * cmd[:, 0] - yaw.sin() * cmd[:, 1], yaw.sin() * cmd[:, 0] + yaw.cos() * cmd[:, 1]], -1
        )
        self.push_elapsed[ids] = 0.0
        self.push_max_deviation[ids] = 0.0
        self.push_window[ids] = int(round(self.cfg.push.window_s / self.dt))
        self.push_countdown[ids] = self._push_interval(n)

    @property
    def after_push(self) -> torch.Tensor:
        """[N] bool: inside the window after a push (the paper's I_after-disturb)."""
        return self.push_window > 0

    @property
    def push_deviation(self) -> torch.Tensor:
        """[N, 2] base position minus where it would be without the push (x_last + commanded velocity * t)."""
        return self.base_pos[:, :2] - (self.push_origin + self.push_ref_vel * self.push_elapsed.unsqueeze(-1))

    # ---------------------------------------------------------------- observations
    def _frame(self, noise: bool = False) -> torch.Tensor:
        """s_t = [angular velocity, gravity in base frame, q - q_default, dq, a_{t-1}, eta (, command)]."""
        parts = {
            "ang_vel": self.base_ang_vel,
            "gravity": self.projected_gravity,
            "joint_pos": self.joint_pos - self.default_joint_pos,
            "joint_vel": self.joint_vel,
        }
        if noise and self.cfg.observation_noise > 0:
            parts = {
                k: v + self.cfg.observation_noise * NOISE_SCALES[k] * (2 * torch.rand(v.shape, generator=self.generator) - 1)
                for k, v in parts.items()
            }
        frame = [*parts.values(), self.actions, self.action_scale]
        if self.cfg.use_command:
            frame.append(self.commands)
        return torch.cat(frame, dim=-1)

    def get_observations(self) -> TensorDict:
        critic = torch.cat(
            [
                self._frame(),
                self.base_lin_vel,
                self.base_pos[:, 2:3],
                self.foot_contact.float(),
                self.after_push.float().unsqueeze(-1),
                self.push_dir * self.after_push.unsqueeze(-1),
                self.push_deviation * self.after_push.unsqueeze(-1),
            ],
            dim=-1,
        )
        return TensorDict(
            {
                "policy": self.frames.flatten(1).clone(),
                "preference": self.preference.clone(),
                "critic": critic,
                "amp": self.amp_frames.flatten(1).clone(),
            },
            batch_size=[self.num_envs],
        )

    # ---------------------------------------------------------------- step
    def step(self, actions: torch.Tensor) -> tuple[TensorDict, torch.Tensor, torch.Tensor, dict]:
        self.last_actions = self.actions.clone()
        self.actions = actions.detach().to("cpu").float().clamp(-self.cfg.action_clip, self.cfg.action_clip)
        target = self.default_joint_pos + self.action_scale * self.actions
        self._apply_pushes()
        self._before_physics()
        self.physics.step(target.double().numpy())
        unstable = self._unstable_envs()
        self._read_state()
        self._update_contacts()
        self.episode_length_buf += 1
        self.push_elapsed += self.dt
        inside = self.after_push
        self.push_max_deviation = torch.where(
            inside, torch.maximum(self.push_max_deviation, self.push_deviation.norm(dim=-1)), self.push_max_deviation
        )

        reward_groups = self._compute_rewards()
        terminated = self._terminated() | unstable
        time_outs = (self.episode_length_buf >= self.max_episode_length) & ~terminated
        dones = terminated | time_outs
        reward = reward_groups[:, 0] + (self.preference * reward_groups[:, 1:]).sum(-1)
        self.episode_sums += reward_groups
        self._accumulate_metrics(push_window_closing=inside & (self.push_window == 1))
        self.push_window = (self.push_window - 1).clamp(min=0)

        done_ids = dones.nonzero(as_tuple=False).squeeze(-1)
        finished = {"env_ids": done_ids, "fell": terminated[done_ids], **self.episode_metrics(done_ids)}
        log = self._episode_log(done_ids, finished)
        self._reset(done_ids)
        if self.cfg.preference_resample_prob > 0 and self.preferences.held is None:
            resample = torch.rand(self.num_envs, generator=self.generator) < self.cfg.preference_resample_prob
            self.preferences.resample(resample.nonzero(as_tuple=False).squeeze(-1))
        self.frames[:, 1:] = self.frames[:, :-1].clone()
        self.frames[:, 0] = self._frame(noise=True)
        self.amp_frames[:, :-1] = self.amp_frames[:, 1:].clone()
        self.amp_frames[:, -1] = self.joint_pos
        extras = {"time_outs": time_outs, "reward_groups": reward_groups, "log": log, "episode_metrics": finished}
        return self.get_observations(), reward, dones, extras

    def _before_physics(self) -> None:
        """Hook for tasks: set external forces or curricula right before the physics step."""

    def _unstable_envs(self) -> torch.Tensor:
        """Envs whose physics diverged (NaN/inf or absurd velocities); they are reset and counted."""
        state = self.physics.state
        bad = ~np.isfinite(state).all(axis=1) | (np.abs(state[:, self.physics.qvel_slice]) > 1e3).any(axis=1)
        if bad.any():
            self.unstable_resets += int(bad.sum())
            good_rows = np.nan_to_num(state[bad], nan=0.0, posinf=0.0, neginf=0.0)
            state[bad] = good_rows
            self.physics.substep_sensors[bad] = 0.0
            self.physics.substep_states[bad] = 0.0
        return torch.from_numpy(bad)

    def _terminated(self) -> torch.Tensor:
        fallen = self.base_pos[:, 2] < self.cfg.termination_height
        tilted = self.projected_gravity[:, :2].norm(dim=-1) > self.cfg.termination_tilt
        return fallen | tilted

    def _compute_rewards(self) -> torch.Tensor:
        """[N, 1 + m]: each term's weight * value * dt summed into its group (objectives unweighted by lambda)."""
        groups = torch.zeros(self.num_envs, 1 + self.num_objectives)
        for func, term in self.reward_terms:
            groups[:, self.group_index[term.group]] += term.weight * func(self, **term.params) * self.dt
        return groups

    # ---------------------------------------------------------------- logging
    def metrics(self) -> dict[str, torch.Tensor]:
        """Per-step quantities the task's metrics average; override or extend per task."""
        return {}

    def _accumulate_metrics(self, push_window_closing: torch.Tensor) -> None:
        values = {
            "stride_sum": self.stride.sum(-1),
            "touchdowns": self.first_contact.float().sum(-1),
            "push_deviation_sum": torch.where(push_window_closing, self.push_max_deviation, 0.0),
            "pushes": push_window_closing.float(),
            **self.metrics(),
        }
        for key, value in values.items():
            if key not in self.metric_sums:
                self.metric_sums[key] = torch.zeros(self.num_envs)
            self.metric_sums[key] += value

    def episode_metrics(self, env_ids: torch.Tensor) -> dict[str, torch.Tensor]:
        """Metrics of finished episodes, each [len(env_ids)] (NaN where undefined, e.g. no push happened)."""
        s = {k: v[env_ids] for k, v in self.metric_sums.items()}
        nan = torch.tensor(float("nan"))
        return {
            "stride_length": torch.where(s["touchdowns"] > 0, s["stride_sum"] / s["touchdowns"].clamp(min=1), nan),
            "push_deviation": torch.where(s["pushes"] > 0, s["push_deviation_sum"] / s["pushes"].clamp(min=1), nan),
        }

    def _episode_log(self, done_ids: torch.Tensor, finished: dict[str, torch.Tensor]) -> dict:
        log = {"Episode_Termination/unstable_resets_total": torch.tensor(float(self.unstable_resets))}
        if len(done_ids) == 0:
            return log
        sums = self.episode_sums[done_ids]
        log["Episode_Reward/task"] = sums[:, 0].mean()
        for i, name in enumerate(self.cfg.objective_names):
            log[f"Episode_Objective/{name}"] = sums[:, 1 + i].mean()
        for key, value in finished.items():
            if key in ("env_ids", "fell"):
                continue
            value = value[~value.isnan()]
            if len(value):
                log[f"Metrics/{key}"] = value.mean()
        log["Episode_Termination/fall"] = finished["fell"].float().mean()
        return log
