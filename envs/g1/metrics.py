"""Per-episode sums of step quantities, turned into the paper's metrics when an episode ends."""

from __future__ import annotations

import math

import torch

from pchc_rsl.envs.g1.contacts import median_from_histogram

GAIT_SETTLE_S = 0.5
"""The per-foot gait figures (swing time, forward step) leave out the touchdowns of an episode's first 0.5 s: the
first steps out of the standing start are not the gait."""


class EpisodeSums:
    """Running sums per env of named per-step quantities; reading them has no side effect."""

    def __init__(self, num_envs: int, device: str = "cpu") -> None:
        self.num_envs, self.device = num_envs, device
        self.sums: dict[str, torch.Tensor] = {}

    def add(self, values: dict[str, torch.Tensor]) -> None:
        for key, value in values.items():
            if key not in self.sums:  # [N] or [N, ...] (a histogram per env)
                self.sums[key] = torch.zeros_like(value, device=self.device)
            self.sums[key] += value

    def get(self, env_ids: torch.Tensor) -> dict[str, torch.Tensor]:
        return {k: v[env_ids] for k, v in self.sums.items()}

    def reset(self, env_ids: torch.Tensor) -> None:
        for value in self.sums.values():
            value[env_ids] = 0.0


def ratio(total: torch.Tensor, count: torch.Tensor) -> torch.Tensor:
    """total / count, NaN where count is 0 (a metric undefined in that episode)."""
    return torch.where(count > 0, total / count.clamp(min=1), float("nan"))


def larger_over_smaller(pair: torch.Tensor) -> torch.Tensor:
    """[n, 2] left and right figures -> [n] the larger over the smaller (1: symmetric); NaN where either is NaN or
    not positive (a foot that never stepped forward has no ratio)."""
    low, high = pair.min(dim=-1).values, pair.max(dim=-1).values
    return torch.where(low > 0, high / low.clamp(min=1e-9), float("nan"))


class EpisodeMetrics:
    """A G1 env's episode metrics: gait, speed, steering and push figures, summed step by step and turned into
    figures per episode (``of_episodes``), and the training log of the episodes that ended. Tasks extend it."""

    def __init__(self, env) -> None:
        self.env = env
        n, dev = env.num_envs, env.device
        self.sums = EpisodeSums(n, dev)
        self.reward_sums = torch.zeros(n, 1 + env.num_objectives, device=dev)
        """[N, 1 + m] each reward group's sum over the episode so far."""
        self.origin = torch.zeros(n, 2, device=dev)
        self.start_heading = torch.zeros(n, 2, device=dev)
        """[N, 2] where each episode started and the unit vector of its heading then (lateral drift)."""

    def start(self) -> None:
        """Every per-step quantity gets a (zero) sum, so ``of_episodes`` also answers before a step."""
        self.sums.add({key: torch.zeros_like(value) for key, value in self.step_quantities().items()})

    def reset(self, env_ids: torch.Tensor) -> None:
        """New episodes in these envs: their sums start over from the robot's pose."""
        robot = self.env.robot
        self.origin[env_ids] = robot.base_pos[env_ids, :2]
        self.start_heading[env_ids] = robot.heading[env_ids]
        self.reward_sums[env_ids] = 0.0
        self.sums.reset(env_ids)

    def step_quantities(self) -> dict[str, torch.Tensor]:
        """[N] per-step quantities whose episode sums make the metrics (tasks extend it); no side effects."""
        env = self.env
        pushes, feet, robot, commands = env.pushes, env.feet, env.robot, env.commands
        closing = pushes.active & pushes.closing()
        step = feet.step_vector  # [N, foot, (forward, lateral)], 0 where no touchdown
        air_time_histogram = feet.air_time_histogram()  # [N, foot, bins]
        settled = (env.episode_length_buf * env.dt > GAIT_SETTLE_S).float()  # [N]
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
            "forward_speed_sum": robot.base_lin_vel[:, 0],
            "base_height_sum": robot.base_pos[:, 2],
            "knee_angle_sum": robot.joint_pos[:, env.knee_idx].mean(-1),
            "knee_torque_sq_sum": robot.torques_substeps[:, :, env.knee_idx].square().mean(dim=(1, 2)),
            "command_speed_sum": commands[:, 0],
            "lateral_speed_sum": robot.base_lin_vel[:, 1],
            "lateral_command_sum": commands[:, 1],
            "yaw_change_sum": env.command.turn,
            "yaw_rate_command_sum": commands[:, 2],
            "steps": torch.ones(env.num_envs, device=env.device),
            "push_deviation_sum": torch.where(closing, pushes.max_deviation, 0.0),
            "com_deviation_sum": torch.where(closing, pushes.max_com_deviation, 0.0),
            "pushes": closing.float(),
        }

    def record_step(self, reward_groups: torch.Tensor) -> None:
        """Add this step's reward groups and quantities to the episode sums."""
        self.reward_sums += reward_groups
        self.sums.add(self.step_quantities())

    def push_sums(self, env_ids: torch.Tensor, key: str, open_values: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """Deviation sum and push count of these envs' episodes, counting a push whose window the episode's end cut
        short (a fall, or the time-out) with the deviation it had reached."""
        s = self.sums.get(env_ids)
        open_window = self.env.pushes.active[env_ids]
        total = s[key] + torch.where(open_window, open_values[env_ids], 0.0)
        return total, s["pushes"] + open_window.float()

    def of_episodes(self, env_ids: torch.Tensor) -> dict[str, torch.Tensor]:
        """Metrics of these envs' episodes so far, each [len(env_ids)] (NaN where undefined, e.g. no push)."""
        env = self.env
        dt = env.dt
        s = self.sums.get(env_ids)
        deviation, pushes = self.push_sums(env_ids, "push_deviation_sum", env.pushes.max_deviation)
        touchdowns = s["touchdowns"]
        swing = median_from_histogram(s["settled_air_time_histogram"], dt)  # [n, foot]
        foot_step = ratio(s["settled_forward_step_sum"], s["settled_touchdowns"])  # [n, foot]
        duration = s["steps"] * dt
        turned = s["yaw_change_sum"]  # rad, unwrapped
        start_heading = self.start_heading[env_ids]
        moved = env.robot.base_pos[env_ids, :2] - self.origin[env_ids]
        sideways = -moved[:, 0] * start_heading[:, 1] + moved[:, 1] * start_heading[:, 0]
        return {
            "stride_length": ratio(s["stride_sum"], touchdowns),
            "push_deviation": ratio(deviation, pushes),
            "cadence": ratio(touchdowns, 2 * s["steps"] * dt),
            "air_time": median_from_histogram(s["air_time_histogram"], dt),
            "forward_step": ratio(s["forward_step_sum"], touchdowns),
            "side_step": ratio(s["side_step_sum"], touchdowns),
            "backward_touchdowns": 100.0 * ratio(s["backward_touchdowns"], touchdowns),
            "forward_speed": ratio(s["forward_speed_sum"], s["steps"]),
            "base_height": ratio(s["base_height_sum"], s["steps"]),
            "knee_flexion": ratio(s["knee_angle_sum"], s["steps"]) * (180.0 / math.pi),
            "knee_torque_rms": ratio(s["knee_torque_sq_sum"], s["steps"]).sqrt(),
            "command_speed": ratio(s["command_speed_sum"], s["steps"]),
            "air_time_left": swing[:, 0],
            "air_time_right": swing[:, 1],
            "swing_ratio": larger_over_smaller(swing),
            "forward_step_left": foot_step[:, 0],
            "forward_step_right": foot_step[:, 1],
            "step_ratio": larger_over_smaller(foot_step),
            "heading_drift": (turned - s["yaw_rate_command_sum"] * dt).abs() * (180.0 / math.pi),
            "yaw_rate_error": (ratio(turned, duration) - ratio(s["yaw_rate_command_sum"], s["steps"])).abs(),
            "lateral_speed_error": ratio(s["lateral_speed_sum"] - s["lateral_command_sum"], s["steps"]).abs(),
            "lateral_drift": sideways.abs(),
        }

    def log(self, done_ids: torch.Tensor, finished: dict[str, torch.Tensor], unstable: torch.Tensor) -> dict:
        """extras['log']: per finished episode values, NaN where a metric is undefined (an episode without a push);
        the runner's IterationLogger leaves the NaN out of its means. Nothing here waits on the device."""
        log = {
            "Episode_Termination/unstable_resets_total": self.env.unstable_resets.float(),
            "Episode_Termination/unstable_envs": unstable.float(),
        }
        if len(done_ids) == 0:
            return log
        sums = self.reward_sums[done_ids]
        log["Episode_Reward/task"] = sums[:, 0]
        for i, name in enumerate(self.env.cfg.objective_names):
            log[f"Episode_Objective/{name}"] = sums[:, 1 + i]
        for key, value in finished.items():
            if key not in ("env_ids", "fell"):
                log[f"Metrics/{key}"] = value.float()
        log["Episode_Termination/fall"] = finished["fell"].float()
        return log
