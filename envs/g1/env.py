"""The G1 as an rsl-rl VecEnv: batched C MuJoCo physics, task logic in torch over the whole batch.

A task is a G1EnvConfig: which joints, which reward terms (each tagged with its group: "task" or an objective),
pushes, randomisation and terminations. The env sums each group into ``extras["reward_groups"]`` ([N, 1 + m],
objectives raw) and returns r = r_task + sum_i lambda_i r_obj_i, as DESIGN.md specifies.

G1Env only orders the work of its parts, each in its own module: the robot state read from the physics
(``robot``), the velocity command and its references (``command``), foot contacts and strides (``feet``), pushes
(``pushes``), observation histories (``observations``), reward groups (``rewards``) and episode metrics
(``metrics``). Reward terms read those parts.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from tensordict import TensorDict

from rsl_rl.env import VecEnv

from pchc_rsl.envs.g1.action_delay import ActionDelay
from pchc_rsl.envs.g1.commanded_path import rotate
from pchc_rsl.envs.g1.commands import VelocityCommands
from pchc_rsl.envs.g1.config import G1EnvConfig, PushConfig, RandomizationConfig, RewardTerm
from pchc_rsl.envs.g1.contacts import FootContacts
from pchc_rsl.envs.g1.deploy_metadata import deploy_metadata
from pchc_rsl.envs.g1.draws import chance
from pchc_rsl.envs.g1.metrics import EpisodeMetrics
from pchc_rsl.envs.g1.observations import ObservationBuffers
from pchc_rsl.envs.g1.pushes import Pushes, check_push_config
from pchc_rsl.envs.g1.randomization import model_variants
from pchc_rsl.envs.g1.robot_state import RobotState
from pchc_rsl.envs.g1.reward_groups import RewardGroups
from pchc_rsl.envs.physics.backend import make_physics, physics_device
from pchc_rsl.preference import EnvPreferences
from pchc_rsl.robots.g1.constants import STANDING_HEIGHT
from pchc_rsl.robots.g1.model import build_g1_model, default_joint_positions

__all__ = ["G1Env", "G1EnvConfig", "PushConfig", "RandomizationConfig", "RewardTerm"]


class G1Env(VecEnv):
    """N G1 robots; see G1EnvConfig. The env's tensors live where its physics runs: on the CPU with C MuJoCo, on
    ``device`` with MuJoCo Warp (``cfg.physics``)."""

    metrics_class = EpisodeMetrics
    """The task's episode metrics (a subclass of EpisodeMetrics adds the task's own)."""

    def __init__(self, cfg: G1EnvConfig, num_envs: int, device: str = "cpu", seed: int = 0) -> None:
        if cfg.preference_concentration <= 0:
            raise ValueError("preference_concentration must be > 0.")
        self.cfg, self.num_envs = cfg, num_envs
        self.device = physics_device(cfg.physics, device)
        self.num_objectives = len(cfg.objective_names)
        self.num_actions = len(cfg.joints)
        self.dt = cfg.timestep * cfg.decimation
        self.max_episode_length = int(math.ceil(cfg.episode_length_s / self.dt))
        self.generator = torch.Generator(self.device).manual_seed(seed)
        self.rng = np.random.default_rng(seed)

        self.model = build_g1_model(cfg.joints, cfg.timestep, held_joints=tuple(cfg.held_joints))
        variants = model_variants(self.model, cfg.randomization, num_envs, self.rng)
        check_push_config(cfg.push, [self.model.body(i).name for i in range(self.model.nbody)])
        # external forces on bodies: force pushes, a task's own (the fall-recovery assist), the viewers' push button
        self.physics = make_physics(cfg.physics, variants, num_envs, cfg.decimation, cfg.num_threads, self.device,
                                    with_body_forces=True, warp=cfg.warp)
        dev = self.device
        self.robot = RobotState(self.physics, self.model, cfg.joints)
        self.default_joint_pos = torch.tensor(default_joint_positions(cfg.joints), device=dev)
        held = [int(self.model.jnt_qposadr[self.model.joint(j).id]) for j in cfg.held_joints]
        self._held_qpos_idx = torch.tensor(held, dtype=torch.long, device=dev)
        self._held_qpos = torch.tensor(self.model.qpos_spring[held], dtype=torch.float64, device=dev)
        ranges = torch.tensor(self.model.jnt_range[[self.model.joint(j).id for j in cfg.joints]], dtype=torch.float32,
                              device=dev)
        half = 0.45 * (ranges[:, 1:] - ranges[:, :1])
        self.soft_joint_limits = ranges.mean(-1, keepdim=True) + half * torch.tensor([-1.0, 1.0], device=dev)
        self.knee_idx = torch.tensor([i for i, j in enumerate(cfg.joints) if "knee" in j], dtype=torch.long,
                                     device=dev)

        n = num_envs
        self.rewards = RewardGroups(cfg.rewards, cfg.objective_names, self.dt)
        self.feet = FootContacts(n, self.dt, cfg.contact_force_threshold, dev)
        pushed_bodies = cfg.push.force.bodies if cfg.push.force.share > 0 else {}
        self.pushes = Pushes(cfg.push, n, self.dt, self.generator,
                             body_ids={b: self.model.body(b).id for b in pushed_bodies},
                             robot_mass=float(self.model.body_mass.sum()))
        self.observations = ObservationBuffers(n, self.num_actions, cfg.history_length, cfg.amp_window,
                                               cfg.use_command, cfg.observation_noise, self.generator,
                                               amp_root_velocity=cfg.amp_root_velocity, dt=self.dt)
        self.actions = torch.zeros(n, self.num_actions, device=dev)
        self.last_actions = torch.zeros(n, self.num_actions, device=dev)
        self.joint_targets = torch.zeros(n, self.num_actions, device=dev)
        """The position targets the actuators hold now (what a delayed action replaces part-way through a step)."""
        self.action_delay = ActionDelay(cfg.action_delay_s, cfg.timestep, cfg.decimation, n, self.generator)
        self.episode_length_buf = torch.zeros(n, dtype=torch.long, device=dev)
        self.command = VelocityCommands(cfg, n, self.dt, self.max_episode_length, self.generator)
        self.preferences = EnvPreferences(n, self.num_objectives, cfg.preference_concentration, self.generator, dev)
        self.preference = self.preferences.values
        self.action_scale = torch.full((n, 1), cfg.action_scale, device=dev)
        model = self.model
        self.joint_action_weights = (  # [J]: effort limit / kp per actuator, or 1
            torch.tensor(model.actuator_forcerange[:, 1] / model.actuator_gainprm[:, 0], dtype=torch.float32,
                         device=dev)
            if cfg.action_scale_per_joint else torch.ones(self.num_actions, device=dev)
        )
        self.unstable_resets = torch.zeros((), dtype=torch.long, device=dev)
        self.metrics = self.metrics_class(self)
        self.reset()
        self.metrics.start()

    @property
    def commands(self) -> torch.Tensor:
        """[N, (v_x, v_y, w_z)] the velocity command each robot follows now (writable in place)."""
        return self.command.values

    # ---------------------------------------------------------------- preference
    def set_preference(self, lam) -> None:
        """Hold lambda ([m] for all envs or [N, m]) from now on, across resets; ``None`` resumes sampling."""
        self.preferences.hold(lam)

    # ---------------------------------------------------------------- reset
    def reset(self, env_ids: torch.Tensor | None = None) -> None:
        """Start new episodes in these envs (all by default): initial state, command, preference, histories."""
        ids = (torch.arange(self.num_envs, device=self.device) if env_ids is None
               else torch.as_tensor(env_ids, dtype=torch.long, device=self.device))
        if len(ids) == 0:
            return
        self._before_reset(ids)
        qpos, qvel = self.initial_state(ids)
        self.physics.set_qpos_qvel(ids, qpos, qvel)
        self.robot.read()
        self.command.reset(ids)
        self.action_delay.reset(ids)
        self.preferences.resample(ids)
        self.actions[ids] = 0.0
        self.last_actions[ids] = 0.0
        self.joint_targets[ids] = self.default_joint_pos
        self.episode_length_buf[ids] = 0
        restarted = torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)
        restarted[ids] = True
        self.command.restart_tracking(ids, restarted, self.robot)
        self.feet.reset(ids, self.robot.foot_touch_substeps, self.robot.foot_pos, self.cfg.planted_foot_height)
        self.pushes.reset(ids)
        self.metrics.reset(ids)
        self.observations.reset(self, ids)

    def _chance(self, n: int, probability: float) -> torch.Tensor:
        """[n] bools, each True with ``probability`` (from the env's generator)."""
        return chance(self.generator, n, probability)

    def initial_state(self, env_ids: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Standing at the default pose with joint noise (tasks override for other starts). [n, nq], [n, nv]."""
        n = len(env_ids)
        qpos = torch.zeros(n, self.model.nq, device=self.device, dtype=torch.float64)
        qpos[:, 2] = STANDING_HEIGHT
        qpos[:, 3] = 1.0
        noise = self.cfg.initial_joint_noise * (
            2 * torch.rand(n, self.num_actions, generator=self.generator, device=self.device) - 1)
        qpos[:, self.robot.joint_qpos_idx] = (self.default_joint_pos + noise).double()
        qpos[:, self._held_qpos_idx] = self._held_qpos  # held joints at their spring's rest
        return qpos, torch.zeros(n, self.model.nv, device=self.device, dtype=torch.float64)

    # ---------------------------------------------------------------- observations
    def privileged_parts(self) -> list[tuple[str, torch.Tensor]]:
        """The critic's extra state by quantity: base velocity and height, foot contacts, the push and the deviation
        from it (with ``critic_push_timing`` the push's timing, with ``critic_push_size`` its size, with
        ``critic_command_state`` the state the task's holds read). Names say how the left-right mirror acts on each
        (envs/g1/symmetry.py)."""
        active = self.pushes.active.float().unsqueeze(-1)
        parts = [
            ("base_lin_vel", self.robot.base_lin_vel),
            ("base_height", self.robot.base_pos[:, 2:3]),
            ("foot_contact", self.feet.contact.float()),
            ("push_active", active),
            ("push_direction_xy", self.pushes.direction * active),
            ("push_deviation_xy", self.pushes.deviation(self.robot) * active),
        ]
        if self.cfg.critic_push_timing:
            parts.append(("push_timing", self.pushes.timing()))
        if self.cfg.critic_command_state:
            offset = rotate(self.command.path.error(self.robot.base_pos[:, :2]), -self.robot.yaw)
            parts += [("path_error_xy", offset), ("heading_error", self.command.heading_error.unsqueeze(-1)),
                      ("velocity_average", self.command.velocity_average)]
        if self.cfg.critic_push_size:  # last: pchc-train --init-from widens a critic at the end of its input
            parts.append(("push_size", self.pushes.size.unsqueeze(-1) * active))
        return parts

    def privileged_state(self) -> torch.Tensor:
        """[N, P] the privileged parts, concatenated."""
        return torch.cat([value for _, value in self.privileged_parts()], dim=-1)

    def get_observations(self) -> TensorDict:
        return self.observations.groups(self, self.privileged_state())

    # ---------------------------------------------------------------- step
    def step(self, actions: torch.Tensor) -> tuple[TensorDict, torch.Tensor, torch.Tensor, dict]:
        self.last_actions = self.actions.clone()
        self.actions = actions.detach().to(self.device).float().clamp(-self.cfg.action_clip, self.cfg.action_clip)
        target = self.default_joint_pos + self.action_scale * self.joint_action_weights * self.actions
        self.pushes.apply(self.physics, self.robot, self.commands, self._push_eligible())
        self._before_physics()
        self.pushes.add_forces(self.physics)
        self.physics.step(self.action_delay.control(target, self.joint_targets).to(self.physics.qpos.dtype))
        self.joint_targets = target
        unstable = self._unstable_envs()
        self.robot.read()
        self.feet.update(self.robot.foot_touch_substeps, self.robot.foot_pos, self.robot.heading)
        self.episode_length_buf += 1
        self.pushes.track(self.robot, self.commands)
        self.command.track(self.robot, self.pushes.active)
        self._after_physics()

        reward_groups = self.rewards.compute(self)
        reward_groups.masked_fill_(unstable.unsqueeze(-1), 0.0)  # diverged physics earns nothing; reset and counted
        terminated = self._terminated() | unstable
        time_outs = (self.episode_length_buf >= self.max_episode_length) & ~terminated
        dones = terminated | time_outs
        reward = reward_groups[:, 0] + (self.preference * reward_groups[:, 1:]).sum(-1)
        self.metrics.record_step(reward_groups)
        self.pushes.advance_window()
        self.observations.push_amp(self)
        amp_before_reset = self.observations.amp.flatten(1).clone()

        done_ids = dones.nonzero(as_tuple=False).squeeze(-1)
        finished = {"env_ids": done_ids, "fell": terminated[done_ids], **self.metrics.of_episodes(done_ids)}
        log = self.metrics.log(done_ids, finished, unstable.sum())
        self.reset(done_ids)
        if self.cfg.preference_resample_prob > 0 and self.preferences.held is None:
            resample = (torch.rand(self.num_envs, generator=self.generator, device=self.device)
                        < self.cfg.preference_resample_prob)
            self.preferences.resample_where(resample)
        self.command.resample_due(self.robot)
        self.observations.push(self, amp=False)
        extras = {"time_outs": time_outs, "reward_groups": reward_groups, "log": log, "episode_metrics": finished,
                  "amp_observations": amp_before_reset}
        return self.get_observations(), reward, dones, extras

    # ---------------------------------------------------------------- hooks for tasks
    def _before_reset(self, env_ids: torch.Tensor) -> None:
        """Called with the envs about to reset, while their finished episode's state is still there."""

    def _before_physics(self) -> None:
        """Set external forces or curricula right before the physics step (the pushes' forces are added after);
        without a task's own forces, none."""
        if self.physics.body_forces is not None:
            self.physics.body_forces.zero_()

    def _after_physics(self) -> None:
        """Update task state from the new physics state, before rewards and metrics."""

    def _push_eligible(self) -> torch.Tensor | None:
        """[N] bool: envs whose push countdown runs this step (None: all)."""
        return None

    def fell_this_step(self) -> torch.Tensor:
        """[N] bool: the robot fell at this step (walking: a fall ends the episode, so a termination is one)."""
        return self._terminated()

    def _terminated(self) -> torch.Tensor:
        fallen = self.robot.base_pos[:, 2] < self.cfg.termination_height
        tilted = self.robot.projected_gravity[:, :2].norm(dim=-1) > self.cfg.termination_tilt
        return fallen | tilted

    def _unstable_envs(self) -> torch.Tensor:
        """Envs whose physics diverged (MuJoCo reset them, NaN/inf, or absurd velocities); sanitised, reset and
        counted, on the device (no host sync)."""
        p = self.physics
        bad = p.diverged | ~p.qpos.isfinite().all(-1) | ~(p.qvel.abs() <= 1e3).all(-1)  # NaN fails the <=
        self.unstable_resets += bad.sum()
        p.sanitize(bad)
        return bad

    def physics_report(self) -> dict[str, float]:
        """Read once per training iteration: the physics' buffer and solver peaks since the last call (MuJoCo Warp;
        raises PhysicsOverflow when a buffer overflowed); empty for C MuJoCo, which grows its buffers itself."""
        report = getattr(self.physics, "overflow_report", None)
        return report() if report is not None else {}

    @property
    def amp_root_velocity(self) -> bool:
        """Whether the amp frames hold the base's velocity after the joints (MultiCriticPPO.resolve_amp_config)."""
        return self.cfg.amp_root_velocity

    def joint_ranges(self, names: list[str]) -> list[tuple[float, float]]:
        """The model's range (rad) of each named joint: what a motion clip for this robot must stay within."""
        return [tuple(float(x) for x in self.model.jnt_range[self.model.joint(name).id]) for name in names]

    # ---------------------------------------------------------------- metrics and deployment
    def episode_metrics(self, env_ids: torch.Tensor) -> dict[str, torch.Tensor]:
        """Metrics of these envs' episodes so far, each [len(env_ids)] (NaN where undefined, e.g. no push)."""
        return self.metrics.of_episodes(env_ids)

    def deploy_metadata(self) -> dict:
        """What running this policy on a robot needs (envs/g1/deploy_metadata.py)."""
        return deploy_metadata(self)

    # ---------------------------------------------------------------- checkpointed state
    def state_dict(self) -> dict:
        """What a resumed run needs to continue this env's random streams (the physics state restarts)."""
        return {"generator": self.generator.get_state(), "rng": self.rng.bit_generator.state}

    def load_state_dict(self, state: dict) -> None:
        """Continue the saved streams; a released checkpoint has none (the env keeps its own seeded ones)."""
        if "generator" in state:
            self.generator.set_state(state["generator"])
        if "rng" in state:
            self.rng.bit_generator.state = state["rng"]
