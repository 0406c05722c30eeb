"""rsl-rl's symmetry extension with the mirror loss read from the PPO pass it follows, not from a second pass.

With data augmentation on, each PPO mini-batch holds the original samples and their mirrors, and PPO has just run
the actor on all of them; rsl-rl's mirror loss then runs the actor a second time on the same observations with the
same weights, for the same action means. Reading the means of the first pass gives the same loss, and the same
gradient (one graph instead of two), for one actor pass of the doubled batch less per mini-batch: the largest single
cost of the G1 update after the backward pass (docs/results/training_speed.md).
"""

from __future__ import annotations

import torch
from torch import nn

from rsl_rl.extensions import Symmetry
from rsl_rl.models import MLPModel
from rsl_rl.storage import RolloutStorage


class SharedPassSymmetry(Symmetry):
    """Symmetry whose ``compute_loss`` reuses ``actor.output_distribution_params[0]`` (the action means PPO's pass
    just computed on the augmented batch) when the batch was augmented; otherwise rsl-rl's own."""

    def compute_loss(self, actor: MLPModel, batch: RolloutStorage.Batch, original_batch_size: int) -> torch.Tensor:
        if not self.use_data_augmentation:
            return super().compute_loss(actor, batch, original_batch_size)
        mean_actions = actor.output_distribution_params[0]  # [2B, A]: originals, then mirrors
        if mean_actions.shape[0] != batch.observations.batch_size[0]:
            raise RuntimeError(f"the actor's last pass saw {mean_actions.shape[0]} samples, the augmented batch has "
                               f"{batch.observations.batch_size[0]}: compute_loss must follow PPO's pass on it.")
        _, mirrored = self.data_augmentation_func(env=self.env, obs=None, actions=mean_actions[:original_batch_size])
        loss = nn.functional.mse_loss(mean_actions[original_batch_size:], mirrored.detach()[original_batch_size:])
        return loss if self.use_mirror_loss else loss.detach()
