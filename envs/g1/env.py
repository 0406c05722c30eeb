"""The G1 as an rsl-rl VecEnv: batched C MuJoCo physics, task logic in torch over the whole batch.

A task is a G1EnvConfig: which joints, which reward terms (each tagged with its group: "task" or an objective),
pushes, randomisation and terminations. The env sums each group into ``extras["reward_groups"]`` ([N, 1 + m],
objectives raw) and returns r = r_task + sum_i lambda_i r_obj_i, as DESIGN.md specifies.

G1Env only orders the work of its parts, each in its own module: the robot state read from the physics
(``robot``), foot contacts and strides (``feet``), pushes (``pushes``), observation histories
(``observations``), reward groups (``rewards``) and per-episode sums (``episode``). Reward terms read those parts.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from tensordict import TensorDict

from rsl_rl.env import VecEnv

from pchc_rsl.envs.g1.commanded_path import CommandedPath, rotate
from pchc_rsl.envs.g1.config import G1EnvConfig, PushConfig, RandomizationConfig, RewardTerm
from pchc_rsl.envs.g1.contacts import FootContacts, median_from_histogram
from pchc_rsl.envs.g1.metrics import EpisodeSums, larger_over_smaller, ratio
from pchc_rsl.envs.g1.observations import ObservationBuffers
from pchc_rsl.envs.g1.pushes import Pushes
from pchc_rsl.envs.g1.randomization import model_variants
from pchc_rsl.envs.g1.robot_state import RobotState
from pchc_rsl.envs.physics.backend import make_physics, physics_device
from pchc_rsl.envs.g1.reward_groups import RewardGroups
from pchc_rsl.preference import EnvPreferences
from pchc_rsl.robots.g1.constants import STANDING_HEIGHT, holding_gains
from pchc_rsl.robots.g1.model import build_g1_model, default_joint_positions

GAIT_SETTLE_S = 0.5
"""The per-foot gait figures (swing time, forward step) leave out the touchdowns of an episode's first 0.5 s: the
first steps out of the standing start are not the gait."""


def wrap_angle(angle: torch.Tensor) -> torch.Tensor:
    """Into [-pi, pi)."""
    return torch.remainder(angle + math.pi, 2 * math.pi) - math.pi


__all__ = ["G1Env", "G1EnvConfig", "PushConfig", "RandomizationConfig", "RewardTerm"]


class G1Env(VecEnv):
    """N G1 robots; see G1EnvConfig. The env's tensors live where its physics runs: on the CPU with C MuJoCo, on
    ``device`` with MuJoCo Warp (``cfg.physics``)."""

    uses_body_forces = False
    """Tasks that push bodies with external forces (e.g. the fall-recovery assist) set this."""

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
        self.physics = make_physics(cfg.physics, variants, num_envs, cfg.decimation, cfg.num_threads, self.device,
                                    with_body_forces=self.uses_body_forces, warp=cfg.warp)
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
        self._knee_idx = torch.tensor([i for i, j in enumerate(cfg.joints) if "knee" in j], dtype=torch.long,
                                      device=dev)

        n = num_envs
        self.rewards = RewardGroups(cfg.rewards, cfg.objective_names, self.dt)
        self.feet = FootContacts(n, self.dt, cfg.contact_force_threshold, dev)
        self.pushes = Pushes(cfg.push, n, self.dt, self.generator)
        self.observations = ObservationBuffers(n, self.num_actions, cfg.history_length, cfg.amp_window,
                                               cfg.use_command, cfg.observation_noise, self.generator)
        self.episode = EpisodeSums(n, dev)
        self.actions = torch.zeros(n, self.num_actions, device=dev)
        self.last_actions = torch.zeros(n, self.num_actions, device=dev)
        self.joint_targets = torch.zeros(n, self.num_actions, device=dev)
        """The position targets the actuators hold now (what a delayed action replaces part-way through a step)."""
        self.action_delay = torch.zeros(n, dtype=torch.long, device=dev)
        """Each env's action delay, in physics substeps (see G1EnvConfig.action_delay_s)."""
        self._delay_range = self._substeps_of(cfg.action_delay_s)
        self.episode_length_buf = torch.zeros(n, dtype=torch.long, device=dev)
        self.commands = torch.zeros(n, 3, device=dev)
        self.heading_error = torch.zeros(n, device=dev)
        """[N] the base's yaw minus the yaw its commands integrate to since the command was set (rad, wrapped)."""
        self.commanded_path = CommandedPath(n, self.dt, dev)
        """Where each env's commands take it since the command was set or a push's window closed (the position
        hold's reference; during a window the disturbance objective measures the drift instead)."""
        self.velocity_average = torch.zeros(n, 3, device=dev)
        """[N, (v_x, v_y, w_z)] the base's forward and sideways speed (base frame) and yaw rate, averaged over about
        ``velocity_average_s`` (an exponential average): a walker's velocity sways with every step, and a kernel on
        the instantaneous value pays a walker that is right on average little more than one that is off."""
        self.previous_yaw = torch.zeros(n, device=dev)
        """[N] the base's yaw at the last step (rad): its per-step change, summed, is the turn unwrapped."""
        self.episode_origin = torch.zeros(n, 2, device=dev)
        self.episode_start_heading = torch.zeros(n, 2, device=dev)
        self.command_countdown = torch.zeros(n, dtype=torch.long, device=dev)
        self.preferences = EnvPreferences(n, self.num_objectives, cfg.preference_concentration, self.generator, dev)
        self.preference = self.preferences.values
        self.action_scale = torch.full((n, 1), cfg.action_scale, device=dev)
        model = self.model
        self.joint_action_weights = (  # [J]: effort limit / kp per actuator, or 1
            torch.tensor(model.actuator_forcerange[:, 1] / model.actuator_gainprm[:, 0], dtype=torch.float32,
                         device=dev)
            if cfg.action_scale_per_joint else torch.ones(self.num_actions, device=dev)
        )
        self.episode_reward_sums = torch.zeros(n, 1 + self.num_objectives, device=dev)
        self.unstable_resets = torch.zeros((), dtype=torch.long, device=dev)
        self.reset()
        # every per-step quantity has a (zero) sum from the start, so episode_metrics also answers before a step
        self.episode.add({key: torch.zeros_like(value) for key, value in self.step_metrics().items()})

    def _substeps_of(self, delay_s: tuple[float, float]) -> tuple[int, int]:
        low, high = (int(round(t / self.cfg.timestep)) for t in delay_s)
        if not 0 <= low <= high <= self.cfg.decimation:
            raise ValueError(f"action_delay_s {tuple(delay_s)} must be 0 <= low <= high <= one policy step "
                             f"({self.dt:g} s).")
        return low, high

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
        n = len(ids)
        self.commands[ids] = self.sample_commands(n)
        self.command_countdown[ids] = self._command_interval(n)
        low, high = self._delay_range
        self.action_delay[ids] = torch.randint(low, high + 1, (n,), generator=self.generator, device=self.device)
        self.preferences.resample(ids)
        self.actions[ids] = 0.0
        self.last_actions[ids] = 0.0
        self.joint_targets[ids] = self.default_joint_pos
        self.episode_length_buf[ids] = 0
        self.previous_yaw[ids] = self.robot.yaw[ids]
        self.velocity_average[ids] = 0.0
        self.heading_error[ids] = 0.0
        restarted = torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)
        restarted[ids] = True
        self.commanded_path.restart(restarted, self.robot.base_pos[:, :2], self.robot.yaw)
        self.episode_origin[ids] = self.robot.base_pos[ids, :2]
        self.episode_start_heading[ids] = self.robot.heading[ids]
        self.feet.reset(ids, self.robot.foot_touch_substeps, self.robot.foot_pos, self.cfg.planted_foot_height)
        self.pushes.reset(ids)
        self.episode_reward_sums[ids] = 0.0
        self.episode.reset(ids)
        self.observations.reset(self, ids)

    def sample_commands(self, n: int) -> torch.Tensor:
        """[n, 3] (v_x, v_y, w_z) uniform in the command ranges, zero (stand) with ``zero_command_probability``, one
        axis alone with ``single_axis_probability``."""
        r = self.cfg.command_ranges
        drawn = torch.stack(
            [self._uniform(n, *r["lin_vel_x"]), self._uniform(n, *r["lin_vel_y"]), self._uniform(n, *r["ang_vel_z"])],
            1,
        )
        commands = drawn.clone()
        if self.cfg.zero_yaw_rate_probability > 0:
            straight = self._chance(n, self.cfg.zero_yaw_rate_probability)
            commands[:, 2] = torch.where(straight, 0.0, commands[:, 2])
        if self.cfg.single_axis_probability > 0:
            single = self._chance(n, self.cfg.single_axis_probability)
            axis = torch.randint(0, 3, (n,), generator=self.generator, device=self.device)
            alone = torch.nn.functional.one_hot(axis, 3).bool()
            commands = torch.where(single.unsqueeze(-1), torch.where(alone, drawn, 0.0), commands)
        if self.cfg.zero_command_probability > 0:
            standing = self._chance(n, self.cfg.zero_command_probability)
            commands = torch.where(standing.unsqueeze(-1), 0.0, commands)
        return commands

    def _command_interval(self, n: int) -> torch.Tensor:
        """[n] policy steps until the next command (a step count past the episode's end without resampling)."""
        if self.cfg.command_resample_s is None:
            return torch.full((n,), self.max_episode_length + 1, dtype=torch.long, device=self.device)
        seconds = self._uniform(n, *self.cfg.command_resample_s)
        return (seconds / self.dt).round().long().clamp(min=1)

    def _resample_due_commands(self) -> None:
        """Count down each env's command; where it ran out draw a new one (batched: no host sync)."""
        if self.cfg.command_resample_s is None:
            return
        self.command_countdown -= 1
        due = self.command_countdown <= 0
        self.commands = torch.where(due.unsqueeze(-1), self.sample_commands(self.num_envs), self.commands)
        self.heading_error = torch.where(due, 0.0, self.heading_error)
        self.commanded_path.restart(due, self.robot.base_pos[:, :2], self.robot.yaw)
        self.command_countdown = torch.where(due, self._command_interval(self.num_envs), self.command_countdown)

    def _uniform(self, n: int, low: float, high: float) -> torch.Tensor:
        return low + (high - low) * torch.rand(n, generator=self.generator, device=self.device)

    def _chance(self, n: int, probability: float) -> torch.Tensor:
        """[n] bools, each True with ``probability``."""
        return torch.rand(n, generator=self.generator, device=self.device) < probability

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
        from it (with ``critic_push_timing`` the push's timing, with ``critic_command_state`` the state the task's
        holds read). Names say how the left-right mirror acts on each (envs/g1/symmetry.py)."""
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
            offset = rotate(self.commanded_path.error(self.robot.base_pos[:, :2]), -self.robot.yaw)
            parts += [("path_error_xy", offset), ("heading_error", self.heading_error.unsqueeze(-1)),
                      ("velocity_average", self.velocity_average)]
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
        self.physics.step(self._delayed_control(target).to(self.physics.qpos.dtype))
        self.joint_targets = target
        unstable = self._unstable_envs()
        self.robot.read()
        self.feet.update(self.robot.foot_touch_substeps, self.robot.foot_pos, self.robot.heading)
        self.episode_length_buf += 1
        self.pushes.track(self.robot, self.commands)
        self.commanded_path.advance(self.commands)
        self.commanded_path.restart(self.pushes.active, self.robot.base_pos[:, :2], self.robot.yaw)
        self._after_physics()
        turn = self.yaw_change()
        self.heading_error = wrap_angle(self.heading_error + turn - self.commands[:, 2] * self.dt)
        velocity = torch.cat([self.robot.base_lin_vel[:, :2], (turn / self.dt).unsqueeze(-1)], dim=-1)
        self.velocity_average += min(1.0, self.dt / self.cfg.velocity_average_s) * (velocity - self.velocity_average)

        reward_groups = self.rewards.compute(self)
        reward_groups.masked_fill_(unstable.unsqueeze(-1), 0.0)  # diverged physics earns nothing; reset and counted
        terminated = self._terminated() | unstable
        time_outs = (self.episode_length_buf >= self.max_episode_length) & ~terminated
        dones = terminated | time_outs
        reward = reward_groups[:, 0] + (self.preference * reward_groups[:, 1:]).sum(-1)
        self.episode_reward_sums += reward_groups
        self.record_step_metrics()
        self.pushes.advance_window()
        self.observations.push_amp(self)
        amp_before_reset = self.observations.amp.flatten(1).clone()

        done_ids = dones.nonzero(as_tuple=False).squeeze(-1)
        finished = {"env_ids": done_ids, "fell": terminated[done_ids], **self.episode_metrics(done_ids)}
        log = self._episode_log(done_ids, finished, unstable.sum())
        self.reset(done_ids)
        if self.cfg.preference_resample_prob > 0 and self.preferences.held is None:
            resample = (torch.rand(self.num_envs, generator=self.generator, device=self.device)
                        < self.cfg.preference_resample_prob)
            self.preferences.resample_where(resample)
        self._resample_due_commands()
        self.observations.push(self, amp=False)
        extras = {"time_outs": time_outs, "reward_groups": reward_groups, "log": log, "episode_metrics": finished,
                  "amp_observations": amp_before_reset}
        return self.get_observations(), reward, dones, extras

    def _delayed_control(self, target: torch.Tensor) -> torch.Tensor:
        """[N, J] this step's target -> the control the physics holds: [N, J] without delay, else [N, K, J] with the
        previous target for each env's first ``action_delay`` substeps."""
        if self._delay_range[1] == 0:
            return target
        substep = torch.arange(self.cfg.decimation, device=self.device)
        held = (substep.unsqueeze(0) < self.action_delay.unsqueeze(1)).unsqueeze(-1)  # [N, K, 1]
        return torch.where(held, self.joint_targets.unsqueeze(1), target.unsqueeze(1))

    # ---------------------------------------------------------------- hooks for tasks
    def _before_reset(self, env_ids: torch.Tensor) -> None:
        """Called with the envs about to reset, while their finished episode's state is still there."""

    def _before_physics(self) -> None:
        """Set external forces or curricula right before the physics step."""

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

    # ---------------------------------------------------------------- metrics
    def step_metrics(self) -> dict[str, torch.Tensor]:
        """[N] per-step quantities whose episode sums make the metrics (tasks extend it); no side effects."""
        closing = self.pushes.active & self.pushes.closing()
        feet = self.feet
        step = feet.step_vector  # [N, foot, (forward, lateral)], 0 where no touchdown
        air_time_histogram = feet.air_time_histogram()  # [N, foot, bins]
        settled = (self.episode_length_buf * self.dt > GAIT_SETTLE_S).float()  # [N]
        yaw_change = self.yaw_change()
        return {
            "stride_sum": feet.stride.sum(-1),
            "touchdowns": feet.first_contact.float().sum(-1),
            "forward_step_sum": step[..., 0].sum(-1),
            "side_step_sum": step[..., 1].abs().sum(-1),
            "backward_touchdowns": (feet.first_contact & (step[..., 0] < 0)).float().sum(-1),
            "air_time_histogram": air_time_histogram.sum(1),
            "settled_air_time_histogram": air_time_histogram * settled[:, None, None],
            "settled_touchdowns": feet.first_contact.float() * settled[:, None],  # [N, foot]
            "settled_forward_step_sum": step[..., 0] * settled[:, None],  # [N, foot]
            "forward_speed_sum": self.robot.base_lin_vel[:, 0],
            "base_height_sum": self.robot.base_pos[:, 2],
            "knee_angle_sum": self.robot.joint_pos[:, self._knee_idx].mean(-1),
            "command_speed_sum": self.commands[:, 0],
            "lateral_speed_sum": self.robot.base_lin_vel[:, 1],
            "lateral_command_sum": self.commands[:, 1],
            "yaw_change_sum": yaw_change,
            "yaw_rate_command_sum": self.commands[:, 2],
            "steps": torch.ones(self.num_envs, device=self.device),
            "push_deviation_sum": torch.where(closing, self.pushes.max_deviation, 0.0),
            "com_deviation_sum": torch.where(closing, self.pushes.max_com_deviation, 0.0),
            "pushes": closing.float(),
        }

    def yaw_change(self) -> torch.Tensor:
        """[N] the base's turn (rad) since the last step's metrics were recorded."""
        return wrap_angle(self.robot.yaw - self.previous_yaw)

    def record_step_metrics(self) -> None:
        """Add this step's quantities to the episode sums; the yaw they were turned from moves on."""
        self.episode.add(self.step_metrics())
        self.previous_yaw = self.robot.yaw.clone()

    def _push_sums(self, env_ids: torch.Tensor, key: str, open_values: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """Deviation sum and push count of these envs' episodes, counting a push whose window the episode's end cut
        short (a fall, or the time-out) with the deviation it had reached."""
        s = self.episode.get(env_ids)
        open_window = self.pushes.active[env_ids]
        total = s[key] + torch.where(open_window, open_values[env_ids], 0.0)
        return total, s["pushes"] + open_window.float()

    def episode_metrics(self, env_ids: torch.Tensor) -> dict[str, torch.Tensor]:
        """Metrics of these envs' episodes so far, each [len(env_ids)] (NaN where undefined, e.g. no push)."""
        s = self.episode.get(env_ids)
        deviation, pushes = self._push_sums(env_ids, "push_deviation_sum", self.pushes.max_deviation)
        touchdowns = s["touchdowns"]
        swing = median_from_histogram(s["settled_air_time_histogram"], self.dt)  # [n, foot]
        foot_step = ratio(s["settled_forward_step_sum"], s["settled_touchdowns"])  # [n, foot]
        duration = s["steps"] * self.dt
        turned = s["yaw_change_sum"]  # rad, unwrapped
        start_heading = self.episode_start_heading[env_ids]
        moved = self.robot.base_pos[env_ids, :2] - self.episode_origin[env_ids]
        sideways = -moved[:, 0] * start_heading[:, 1] + moved[:, 1] * start_heading[:, 0]
        return {
            "stride_length": ratio(s["stride_sum"], touchdowns),
            "push_deviation": ratio(deviation, pushes),
            "cadence": ratio(touchdowns, 2 * s["steps"] * self.dt),
            "air_time": median_from_histogram(s["air_time_histogram"], self.dt),
            "forward_step": ratio(s["forward_step_sum"], touchdowns),
            "side_step": ratio(s["side_step_sum"], touchdowns),
            "backward_touchdowns": 100.0 * ratio(s["backward_touchdowns"], touchdowns),
            "forward_speed": ratio(s["forward_speed_sum"], s["steps"]),
            "base_height": ratio(s["base_height_sum"], s["steps"]),
            "knee_flexion": ratio(s["knee_angle_sum"], s["steps"]) * (180.0 / math.pi),
            "command_speed": ratio(s["command_speed_sum"], s["steps"]),
            "air_time_left": swing[:, 0],
            "air_time_right": swing[:, 1],
            "swing_ratio": larger_over_smaller(swing),
            "forward_step_left": foot_step[:, 0],
            "forward_step_right": foot_step[:, 1],
            "step_ratio": larger_over_smaller(foot_step),
            "heading_drift": (turned - s["yaw_rate_command_sum"] * self.dt).abs() * (180.0 / math.pi),
            "yaw_rate_error": (ratio(turned, duration) - ratio(s["yaw_rate_command_sum"], s["steps"])).abs(),
            "lateral_speed_error": ratio(s["lateral_speed_sum"] - s["lateral_command_sum"], s["steps"]).abs(),
            "lateral_drift": sideways.abs(),
        }

    def _episode_log(self, done_ids: torch.Tensor, finished: dict[str, torch.Tensor], unstable: torch.Tensor) -> dict:
        """extras['log']: per finished episode values, NaN where a metric is undefined (an episode without a push);
        the runner's IterationLogger leaves the NaN out of its means. Nothing here waits on the device."""
        log = {
            "Episode_Termination/unstable_resets_total": self.unstable_resets.float(),
            "Episode_Termination/unstable_envs": unstable.float(),
        }
        if len(done_ids) == 0:
            return log
        sums = self.episode_reward_sums[done_ids]
        log["Episode_Reward/task"] = sums[:, 0]
        for i, name in enumerate(self.cfg.objective_names):
            log[f"Episode_Objective/{name}"] = sums[:, 1 + i]
        for key, value in finished.items():
            if key not in ("env_ids", "fell"):
                log[f"Metrics/{key}"] = value.float()
        log["Episode_Termination/fall"] = finished["fell"].float()
        return log

    # ---------------------------------------------------------------- deployment
    def deploy_metadata(self) -> dict:
        """What running this policy on a robot needs, from the env itself (the exported ONNX file carries it, so a
        deploy reads nothing from the training config): joints in the policy's order with their PD gains, effort
        limits, default pose and action scale, the observation layout and the control period."""
        model = self.model
        frame = [[name, size] for name, size in self.observations.frame_layout]
        return {
            "format": 1,
            "joint_names": list(self.cfg.joints),
            "kp": [float(x) for x in model.actuator_gainprm[:, 0]],
            "kd": [float(-x) for x in model.actuator_biasprm[:, 2]],
            "effort_limit": [float(x) for x in model.actuator_forcerange[:, 1]],
            "default_joint_pos": self.default_joint_pos.tolist(),
            "action_scale": (self.action_scale[0] * self.joint_action_weights).tolist(),
            "action_scale_eta": float(self.action_scale[0, 0]),  # the frame's eta entry
            "joint_range": [[float(lo), float(hi)] for lo, hi in
                            (model.jnt_range[model.joint(j).id] for j in self.cfg.joints)],
            "action_clip": float(self.cfg.action_clip),
            "target": "q_target = default_joint_pos + action_scale * clip(action, -action_clip, action_clip)",
            "observation": {
                "frame": frame,
                "frames": self.cfg.history_length + 1,
                "order": "newest frame first; each quantity in SI units, unscaled (scale 1)",
                "frame_dim": sum(size for _, size in frame),
                "base_ang_vel_frame": "pelvis (body) frame",
            },
            "control_period_s": float(self.dt),
            "physics_timestep_s": float(self.cfg.timestep),
            "decimation": int(self.cfg.decimation),
            "objective_names": list(self.cfg.objective_names),
            "preference_size": self.num_objectives,
            "held_joints": {j: list(holding_gains(j)) for j in self.cfg.held_joints},  # trained held by PD: kp, kd
            # the velocity command's trained ranges (lin_vel_x, lin_vel_y, ang_vel_z: [low, high]); {} without one
            "command_ranges": ({k: [float(lo), float(hi)] for k, (lo, hi) in self.cfg.command_ranges.items()}
                               if self.cfg.use_command else {}),
        }

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
