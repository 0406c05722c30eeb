"""Start a critic that observes more than the checkpoint's did from the checkpoint's weights.

Why: giving the critic more privileged state (e.g. ``env.critic_command_state``) changes its input size, and a
trained policy continued with a fresh critic would learn from advantages that mean nothing for many iterations. The
new inputs, appended at the end of the critic's observation, start with zero weights and a unit normaliser, so the
widened critic values every state as the checkpoint's did and learns to use them from there.
"""

from __future__ import annotations

import torch
from torch import nn

FIRST_LAYER = "mlp.0.weight"
NORMALISER = "obs_normalizer."


def widen_critic_inputs(saved: dict[str, torch.Tensor], critic: nn.Module) -> int:
    """Widen ``saved`` (a critic's state dict, changed in place) to ``critic``'s observation width; returns how many
    inputs were added (0: nothing was added, or the critics differ otherwise). The first layer reads [normalised
    observation, extra latent] (the preference, in a preference critic): the new columns go between the two."""
    ours = critic.state_dict()
    if FIRST_LAYER not in saved or FIRST_LAYER not in ours:
        return 0  # not an MLP critic: loaded as it is
    old_width, new_width = saved[FIRST_LAYER].shape[1], ours[FIRST_LAYER].shape[1]
    added = new_width - old_width
    if added <= 0 or saved[FIRST_LAYER].shape[0] != ours[FIRST_LAYER].shape[0]:
        return 0  # nothing to widen; loading reports a critic that differs otherwise
    extra_latent = new_width - critic.obs_dim  # what the latent holds after the observation (the preference)
    at = old_width - extra_latent
    weight = saved[FIRST_LAYER]
    saved[FIRST_LAYER] = torch.cat([weight[:, :at], weight.new_zeros(weight.shape[0], added), weight[:, at:]], dim=1)
    for name, fill in (("_mean", 0.0), ("_var", 1.0), ("_std", 1.0)):
        key = NORMALISER + name
        if key in saved:
            statistic = saved[key]
            saved[key] = torch.cat([statistic, statistic.new_full((*statistic.shape[:-1], added), fill)], dim=-1)
    return added
