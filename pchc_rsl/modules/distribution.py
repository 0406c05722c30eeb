"""rsl-rl's Gaussian action distribution, sampled without waiting for the device.

``torch.distributions.Normal.sample`` calls ``torch.normal(mean, std)``, which checks on the host that every std is
>= 0: on a GPU, one sync at every env step. mean + std * eps with eps ~ N(0, 1) is the same distribution (rsl-rl's
std is clamped positive before it gets here), drawn without the check.
"""

from __future__ import annotations

import torch
from torch.distributions import Normal
from rsl_rl.modules import GaussianDistribution as RslRlGaussianDistribution


class GaussianDistribution(RslRlGaussianDistribution):
    """rsl-rl's ``GaussianDistribution`` (same parameters, state dict and log-probabilities); only ``sample``
    differs. Named in a config as ``"pchc_rsl.modules.distribution:GaussianDistribution"``."""

    def scale_std(self, factor: torch.Tensor) -> None:
        """Multiply the current std by ``factor`` ([N, 1], one per sample), as the preference actors do to make
        exploration depend on lambda; log-probabilities, entropy and KL then follow the scaled std."""
        self._distribution = Normal(self._distribution.loc, self._distribution.scale * factor)

    def sample(self) -> torch.Tensor:
        mean, std = self._distribution.loc, self._distribution.scale
        with torch.no_grad():
            return mean + std * torch.randn_like(mean)
