"""G1 fall recovery from prone (the paper's Table I task), structured after HoST (Huang et al. 2025).

Episodes start lying face down (optionally face up) with randomised joints. HoST's curriculum is kept: an upward
assist force on the torso that shrinks as the robot learns to stand, and the action scale eta annealed from 1
towards 0.25 (eta is in the observation). Phase boundary for the metrics: the robot is "standing" from the first
step its pelvis is above 0.7 m (HoST's success height) to the end of the episode; before that it is "recovering".
Success (HoST's rule): the pelvis gets above 0.7 m and never afterwards drops below 0.5 m within the episode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from pchc_rsl.envs.g1.env import G1Env, G1EnvConfig
from pchc_rsl.envs.g1.metrics import EpisodeMetrics, ratio
from pchc_rsl.envs.physics.backend import physics_device

STAND_HEIGHT = 0.7
FALL_HEIGHT = 0.5


def standing_phase(heights: torch.Tensor, stand_height: float = STAND_HEIGHT) -> torch.Tensor:
    """[T] pelvis heights -> [T] bool: True from the first step above stand_height on."""
    return torch.cummax((heights > stand_height).int(), dim=0).values.bool()


def host_success(heights: torch.Tensor, stand_height: float = STAND_HEIGHT, fall_height: float = FALL_HEIGHT) -> bool:
    """HoST's rule on one episode's pelvis heights [T]: above stand_height once, never below fall_height after."""
    standing = standing_phase(heights, stand_height)
    return bool(standing.any() and not (standing & (heights < fall_height)).any())


class FallRecoveryMetrics(EpisodeMetrics):
    """Table I per episode beside the walking figures: energy and torque per phase, COM displacement, success."""

    def step_quantities(self) -> dict[str, torch.Tensor]:
        env = self.env
        standing = env.reached_standing.float()
        # mechanical energy this step, J: sum_k sum_j |tau_j dq_j| * timestep over the substeps
        robot = env.robot
        energy = (robot.torques_substeps * robot.joint_vel_substeps).abs().sum(dim=(1, 2)) * env.cfg.timestep
        torque = robot.torques_substeps.abs().sum(-1).mean(-1)  # Nm, summed over joints, mean over substeps
        return {
            **super().step_quantities(),
            "energy_recovery": energy * (1 - standing),
            "energy_standing": energy * standing,
            "torque_recovery": torque * (1 - standing),
            "torque_standing": torque * standing,
            "steps_recovery": 1 - standing,
            "steps_standing": standing,
        }

    def of_episodes(self, env_ids: torch.Tensor) -> dict[str, torch.Tensor]:
        """Table I per episode. Energy: mean mechanical power sum_j |tau_j dq_j| in J/s, overall and in each phase
        (so, as in the paper's table, the overall figure lies between the phases'); torque: mean over the steps of
        each phase of sum_j |tau_j| (Nm); COM displacement: the whole-body COM's largest horizontal distance from
        its pre-push position within the window after each push, averaged over pushes (m); HoST success. Also
        ``push_deviation``, the same for the pelvis: what r_disturb's position term charges, beside the paper's COM
        figure, since the two need not follow each other (the upper body can move the COM while the pelvis holds)."""
        env = self.env
        s = self.sums.get(env_ids)
        dt = env.dt
        steps = s["steps_recovery"] + s["steps_standing"]
        com, pushes = self.push_sums(env_ids, "com_deviation_sum", env.pushes.max_com_deviation)
        pelvis, _ = self.push_sums(env_ids, "push_deviation_sum", env.pushes.max_deviation)
        return {
            "energy_overall": ratio(s["energy_recovery"] + s["energy_standing"], steps * dt),
            "energy_recovery": ratio(s["energy_recovery"], s["steps_recovery"] * dt),
            "energy_standing": ratio(s["energy_standing"], s["steps_standing"] * dt),
            "torque_overall": ratio(s["torque_recovery"] + s["torque_standing"], steps),
            "torque_recovery": ratio(s["torque_recovery"], s["steps_recovery"]),
            "torque_standing": ratio(s["torque_standing"], s["steps_standing"]),
            "com_displacement": ratio(com, pushes),
            "push_deviation": ratio(pelvis, pushes),
            "success": env.succeeded(env_ids).float(),
        }

    def log(self, done_ids: torch.Tensor, finished: dict[str, torch.Tensor], unstable: torch.Tensor) -> dict:
        log = super().log(done_ids, finished, unstable)
        log["Curriculum/assist_level"] = self.env._assist.clone()
        log["Curriculum/action_scale"] = self.env.action_scale[0, 0].clone()
        return log


@dataclass
class FallRecoveryConfig(G1EnvConfig):
    supine_probability: float = 0.0
    """Share of episodes that start face up instead of face down."""
    initial_height: float = 0.3
    assist_force: float = 200.0
    """Upward force (N) on the torso at curriculum level 1 (the robot weighs about 330 N)."""
    assist_level_step: float = 0.05
    assist_success_threshold: float = 0.7
    """Lower the assist by one step when this share of the last num_envs ended episodes succeeded."""
    eta_initial: float = 1.0
    eta_final: float = 0.25
    eta_anneal_steps: int = 30000
    """Policy steps (per env) over which eta goes linearly from eta_initial to eta_final."""
    curriculum: bool = True
    """False: no assist and eta_final from the start (evaluation)."""
    terminate_on_fall: bool = False
    """End the episode when the robot falls after standing (HoST's failure). Then falling ends the energy cost
    instead of adding a second, costly getting-up, so an energy-preferring policy can trade robustness for energy
    (the paper's Table I); without it a fall's re-standing makes robustness the energy-optimal choice too."""


class G1FallRecoveryEnv(G1Env):
    """G1Env with prone starts, HoST's curriculum, and Table I metrics."""

    metrics_class = FallRecoveryMetrics

    def __init__(self, cfg: FallRecoveryConfig, num_envs: int, device: str = "cpu", seed: int = 0) -> None:
        where = physics_device(cfg.physics, device)  # the reset inside G1Env.__init__ uses what is set here
        self._assist = torch.tensor(1.0 if cfg.curriculum else 0.0, dtype=torch.float64, device=where)
        """The assist level on the env's device: the curriculum updates it without waiting on the device."""
        self.global_steps = 0
        self._ended_episodes = torch.zeros((), dtype=torch.long, device=where)
        self._succeeded_episodes = torch.zeros((), dtype=torch.long, device=where)
        self.reached_standing = torch.zeros(num_envs, dtype=torch.bool, device=where)
        self.fell_after_standing = torch.zeros(num_envs, dtype=torch.bool, device=where)
        self._fell_now = torch.zeros(num_envs, dtype=torch.bool, device=where)
        super().__init__(cfg, num_envs, device, seed)
        self.torso_id = self.model.body("torso_link").id
        self._update_eta()

    def initial_state(self, env_ids: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Lying face down (pitch +90 deg: the body's forward axis points at the floor) with random yaw and joints."""
        qpos, qvel = super().initial_state(env_ids)
        n = len(env_ids)
        supine = self._chance(n, self.cfg.supine_probability)
        pitch = torch.where(supine, -math.pi / 2, math.pi / 2)
        yaw = 2 * math.pi * torch.rand(n, generator=self.generator, device=self.device)
        # q = q_yaw * q_pitch, (w, x, y, z)
        cy, sy, cp, sp = (yaw / 2).cos(), (yaw / 2).sin(), (pitch / 2).cos(), (pitch / 2).sin()
        qpos[:, 3:7] = torch.stack([cy * cp, -sy * sp, cy * sp, sy * cp], -1)
        qpos[:, 2] = self.cfg.initial_height
        return qpos, qvel

    def _before_reset(self, env_ids: torch.Tensor) -> None:
        self._update_assist(env_ids)
        self.reached_standing[env_ids] = False
        self.fell_after_standing[env_ids] = False

    # ---------------------------------------------------------------- curriculum
    @property
    def assist_level(self) -> float:
        """The share of ``assist_force`` lifting the torso now (1 at the start of the curriculum, 0 at its end)."""
        return float(self._assist)

    @assist_level.setter
    def assist_level(self, value: float) -> None:
        self._assist.fill_(value)

    def _update_assist(self, env_ids: torch.Tensor) -> None:
        """HoST-style: shrink the assist once most of the last num_envs ended episodes stood up.

        Judged over num_envs episodes, not over each step's resets: with terminate_on_fall the failures end one by
        one while the successes end together at the time-out, so a per-step share would be biased towards success.
        Without termination all episodes end together and the two rules agree. Counted on the device: episodes that
        never ran (the first reset) do not count."""
        if not self.cfg.curriculum:
            return
        ran = self.episode_length_buf[env_ids] > 0
        self._ended_episodes += ran.sum()
        self._succeeded_episodes += (self.succeeded(env_ids) & ran).sum()
        judged = self._ended_episodes >= self.num_envs
        passed = judged & (self._succeeded_episodes >= self.cfg.assist_success_threshold * self._ended_episodes)
        self._assist.copy_(torch.where(passed, (self._assist - self.cfg.assist_level_step).clamp(min=0.0),
                                       self._assist))
        self._ended_episodes.masked_fill_(judged, 0)
        self._succeeded_episodes.masked_fill_(judged, 0)

    def _update_eta(self) -> None:
        c = self.cfg
        if c.curriculum:
            progress = min(1.0, self.global_steps / max(1, c.eta_anneal_steps))
            eta = c.eta_initial + (c.eta_final - c.eta_initial) * progress
        else:
            eta = c.eta_final
        self.action_scale[:] = eta

    def _before_physics(self) -> None:
        self.physics.body_forces[:] = 0.0
        force = self.cfg.assist_force * self._assist.to(self.physics.body_forces)
        self.physics.body_forces[:, self.torso_id, 2] = force
        self.global_steps += 1
        self._update_eta()

    def _after_physics(self) -> None:
        """HoST's success bookkeeping: stood up (pelvis above 0.7 m), and fell again afterwards (below 0.5 m)."""
        height = self.robot.base_pos[:, 2]
        self.reached_standing |= height > STAND_HEIGHT
        self._fell_now = self.reached_standing & (height < FALL_HEIGHT) & ~self.fell_after_standing
        self.fell_after_standing |= self._fell_now

    def fell_this_step(self) -> torch.Tensor:
        """[N] bool: the first fall after standing happened at this step (with or without terminate_on_fall)."""
        return self._fell_now

    def _push_eligible(self) -> torch.Tensor | None:
        """With ``only_when_standing``: robots that have stood up and are up now (pelvis above the fall height), so
        a robot that fell again is not pushed while it lies or gets up."""
        if not self.cfg.push.only_when_standing:
            return None
        return self.reached_standing & (self.robot.base_pos[:, 2] > FALL_HEIGHT)

    def succeeded(self, env_ids: torch.Tensor) -> torch.Tensor:
        return self.reached_standing[env_ids] & ~self.fell_after_standing[env_ids]

    # ---------------------------------------------------------------- metrics
    def _terminated(self) -> torch.Tensor:
        """Lying down is where this task starts, not a failure: episodes end by time-out, or (terminate_on_fall)
        when the robot falls again after standing."""
        if self.cfg.terminate_on_fall:
            return self.fell_after_standing.clone()
        return torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)

    # ---------------------------------------------------------------- checkpointed state
    def state_dict(self) -> dict:
        """The curriculum (assist level, eta's step counter) travels with the checkpoint: a resumed run continues
        at the assist and action scale it had reached."""
        return {**super().state_dict(), "assist_level": self.assist_level, "global_steps": self.global_steps}

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        self.assist_level = float(state["assist_level"])
        self.global_steps = int(state["global_steps"])
        self._update_eta()
