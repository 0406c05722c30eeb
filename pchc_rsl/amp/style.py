"""AMPStyle: everything MultiCriticPPO needs for the AMP style reward, built from one config dict.

Reference windows come from motion files; policy windows from the env's ``amp`` observation group (a window of
the actuated joint positions, oldest frame first, each frame optionally followed by the root's velocity). The style
reward c * max(0, 1 - (D - 1)^2 / 4) is added to the task group, the discriminator is trained after each PPO update
on replayed policy windows with its own optimiser.
"""

from __future__ import annotations

import torch

from pchc_rsl.amp.discriminator import AMPDiscriminator, ReplayBuffer
from pchc_rsl.amp.motion import ROOT_VELOCITY_SIZE, MotionWindows, kept_frames, load_motions


class AMPStyle:
    def __init__(
        self,
        motion_files: list[str],
        joint_names: list[str],
        fps: float,
        input_dim: int,
        window: int = 5,
        style_reward_scale: float = 0.02,
        grad_penalty_coef: float = 5.0,
        learning_rate: float = 1e-4,
        hidden_dims: tuple[int, ...] | list[int] = (512, 256),
        replay_capacity: int = 100_000,
        num_updates: int = 4,
        batch_size: int = 512,
        obs_group: str = "amp",
        exclude_reference_beyond: dict[str, float] | None = None,
        joint_ranges: list[tuple[float, float]] | None = None,
        penalty_on: str = "reference",
        root_velocity: bool = False,
        device: str = "cpu",
    ) -> None:
        """``exclude_reference_beyond``: joint -> bound (rad) past which a clip's frame is left out of the reference
        (motion.kept_frames); ``joint_ranges``: the robot's range of each AMP joint, which every clip frame must
        respect (motion.load_motion); ``root_velocity``: each frame also holds the root's velocity in its heading
        frame (motion.root_velocity), after the joints."""
        frame = len(joint_names) + (ROOT_VELOCITY_SIZE if root_velocity else 0)
        if input_dim != window * frame:
            extra = f" + {ROOT_VELOCITY_SIZE} root velocity columns" if root_velocity else ""
            raise ValueError(
                f"The '{obs_group}' observation has {input_dim} columns; AMP expects window {window} x "
                f"({len(joint_names)} joints{extra}) = {window * frame} (amp_cfg.window, amp_cfg.root_velocity; "
                "the G1 env: env.amp_window, env.amp_root_velocity)."
            )
        clips = load_motions(motion_files, joint_names, fps, min_frames=window, joint_ranges=joint_ranges,
                             with_root_velocity=root_velocity)
        keep = [kept_frames(c, joint_names, exclude_reference_beyond) for c in clips] if exclude_reference_beyond \
            else None
        self.reference = MotionWindows(clips, window, device, keep)
        self.discriminator = AMPDiscriminator(input_dim, hidden_dims, input_normalization=True).to(device)
        self.learning_rate = learning_rate
        self.optimizer = torch.optim.Adam(self.discriminator.parameters(), lr=learning_rate)
        self.replay = ReplayBuffer(replay_capacity, input_dim, device)
        self.scale, self.grad_penalty_coef = style_reward_scale, grad_penalty_coef
        self.num_updates, self.batch_size, self.penalty_on = num_updates, batch_size, penalty_on
        self.obs_group = obs_group
        frames = sum(len(clip) for clip in clips)
        left_out = f" ({sum(int((~k).sum()) for k in keep)} frames left out)" if keep is not None else ""
        self.summary = (f"AMP: {len(clips)} clip(s), {frames} frames at {fps:g} fps{left_out}, "
                        f"{self.reference.num_windows} reference windows of {window}, style reward scale "
                        f"{style_reward_scale:g}")
        """One line for the user: what the style reward was given."""

    def reward(self, windows: torch.Tensor) -> torch.Tensor:
        """[N] style reward of the policy windows [N, window * joints]; they are kept for the discriminator."""
        self.replay.insert(windows)
        return self.discriminator.style_reward(windows, self.scale)

    def update(self, reduce_gradients=None) -> dict[str, float]:
        """Train D on reference vs replayed policy windows; ``reduce_gradients(params)`` averages across processes."""
        stats: dict[str, float] = {}
        for _ in range(self.num_updates):
            reference = self.reference.sample(self.batch_size)
            policy = self.replay.sample(self.batch_size)
            loss, info = self.discriminator.loss(reference, policy, self.grad_penalty_coef, self.penalty_on)
            self.optimizer.zero_grad()
            loss.backward()
            if reduce_gradients is not None:
                reduce_gradients(self.discriminator.parameters())
            self.optimizer.step()
            self.discriminator.update_normalization(torch.cat([reference, policy]))
            for key, value in info.items():
                stats[key] = stats.get(key, 0.0) + value / self.num_updates
        return stats

    def state_dict(self) -> dict:
        return {"discriminator": self.discriminator.state_dict(), "optimizer": self.optimizer.state_dict(),
                "replay": self.replay.state_dict()}

    def load_state_dict(self, state: dict) -> None:
        self.discriminator.load_state_dict(state["discriminator"])
        if "optimizer" in state:  # released policies carry the discriminator only
            self.optimizer.load_state_dict(state["optimizer"])
            # torch restores the saved learning rate with Adam's moments: keep the one this run was given
            for group in self.optimizer.param_groups:
                group["lr"] = self.learning_rate
        if "replay" in state:  # without it (older checkpoints, released policies) the buffer starts empty
            self.replay.load_state_dict(state["replay"])
