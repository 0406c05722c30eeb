"""The AMP discriminator (least-squares GAN with a gradient penalty) and its replay buffer of policy windows.

D scores a window of AMP states [B, window * J]: trained towards +1 on reference motion and -1 on the policy, so the
style reward c * max(0, 1 - (D - 1)^2 / 4) is c on motion D takes for reference and 0 at D <= -1. The gradient
penalty on the reference samples keeps D flat around the reference manifold, which keeps that reward informative.
"""

from __future__ import annotations

import torch
import torch.nn as nn

from rsl_rl.modules import MLP, EmpiricalNormalization


PENALTY_PLACES = ("reference", "interpolates")
"""Where the gradient penalty is taken (AMPDiscriminator.loss)."""


class AMPDiscriminator(nn.Module):
    """MLP on a window of AMP states: [B, input_dim] -> [B] scalar D, optionally on empirically normalised input."""

    def __init__(
        self,
        input_dim: int,
        hidden_dims: tuple[int, ...] | list[int] = (512, 256),
        activation: str = "elu",
        input_normalization: bool = False,
    ) -> None:
        super().__init__()
        self.input_dim = input_dim
        self.input_normalization = input_normalization
        self.normalizer: nn.Module = EmpiricalNormalization(input_dim) if input_normalization else nn.Identity()
        self.mlp = MLP(input_dim, 1, list(hidden_dims), activation)

    def _check(self, x: torch.Tensor, name: str) -> None:
        if x.dim() != 2 or x.shape[1] != self.input_dim:
            raise ValueError(f"{name} must be [B, {self.input_dim}] AMP windows, got shape {list(x.shape)}.")

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """[B, input_dim] -> [B]."""
        return self.mlp(self.normalizer(x)).squeeze(-1)

    def update_normalization(self, x: torch.Tensor) -> None:
        """Add [B, input_dim] windows to the running input statistics (no-op without input_normalization)."""
        if self.input_normalization:
            self._check(x, "x")
            self.normalizer.update(x)

    def loss(
        self, reference: torch.Tensor, policy: torch.Tensor, grad_penalty_coef: float, penalty_on: str = "reference"
    ) -> tuple[torch.Tensor, dict[str, float]]:
        """Least-squares GAN loss with a zero-centred gradient penalty (the AMP paper's, on the reference samples).

            L = mean (D(ref) - 1)^2 + mean (D(policy) + 1)^2 + (alpha_d / 2) mean ||grad_x D(x)||^2

        The PCHC paper prints the penalty as ||grad_phi D||_2 (unsquared, w.r.t. phi); we follow the AMP paper it
        builds on: the squared norm of the gradient w.r.t. the input. ``penalty_on`` says where x is taken:
        "reference" (the AMP paper: D is smooth around the clips, free elsewhere) or "interpolates" (points drawn
        uniformly on the segments between reference and policy samples: D has to climb from -1 to +1 along the
        whole way between them, so it keeps a slope where the policy is instead of a step next to the clips, and the
        style reward pulls a policy that starts far from them; docs/design.md, "A style reward that pulls").
        x is the normalised input (the raw input without input_normalization). reference [B_r, input_dim],
        policy [B_p, input_dim]. Returns (L, logging dict of floats).
        """
        self._check(reference, "reference")
        self._check(policy, "policy")
        if grad_penalty_coef < 0:
            raise ValueError(f"grad_penalty_coef (alpha_d) must be >= 0, got {grad_penalty_coef}.")
        if penalty_on not in PENALTY_PLACES:
            raise ValueError(f"penalty_on '{penalty_on}' is not one of {', '.join(PENALTY_PLACES)}.")
        ref_input = self.normalizer(reference).detach().requires_grad_(True)
        d_ref = self.mlp(ref_input).squeeze(-1)
        d_policy = self(policy)
        loss_ref = (d_ref - 1.0).square().mean()
        loss_policy = (d_policy + 1.0).square().mean()
        if penalty_on == "reference":
            at, d_at = ref_input, d_ref
        else:
            policy_input = self.normalizer(policy).detach()
            n = min(len(ref_input), len(policy_input))
            share = torch.rand(n, 1, device=policy_input.device)
            at = (share * ref_input[:n].detach() + (1 - share) * policy_input[:n]).requires_grad_(True)
            d_at = self.mlp(at).squeeze(-1)
        # create_graph so the penalty itself is differentiated w.r.t. the parameters; retain_graph so that without a
        # penalty (create_graph=False) the loss can still be backpropagated through d_ref
        (grad,) = torch.autograd.grad(d_at.sum(), at, create_graph=grad_penalty_coef > 0, retain_graph=True)
        grad_penalty = grad.square().sum(dim=-1).mean()
        total = loss_ref + loss_policy + 0.5 * grad_penalty_coef * grad_penalty
        info = {
            "amp/loss_ref": loss_ref.item(),
            "amp/loss_policy": loss_policy.item(),
            "amp/grad_penalty": grad_penalty.item(),
            "amp/d_ref": d_ref.mean().item(),
            "amp/d_policy": d_policy.mean().item(),
        }
        return total, info

    def style_reward(self, windows: torch.Tensor, scale_c: float) -> torch.Tensor:
        """c * max(0, 1 - (D - 1)^2 / 4) of [B, input_dim] windows. Returns [B] in [0, c], without gradients."""
        self._check(windows, "windows")
        with torch.no_grad():
            d = self(windows)
            return scale_c * torch.clamp(1.0 - 0.25 * (d - 1.0).square(), min=0.0)


class ReplayBuffer:
    """Ring buffer of the latest ``capacity`` policy windows [capacity, dim].

    The discriminator trains on policy samples from many past iterations, not only the newest rollout, which keeps it
    from overfitting to (and oscillating with) the current policy.
    """

    def __init__(self, capacity: int, dim: int, device: str | torch.device = "cpu") -> None:
        if capacity < 1 or dim < 1:
            raise ValueError(f"ReplayBuffer needs capacity >= 1 and dim >= 1, got capacity={capacity}, dim={dim}.")
        self.capacity = capacity
        self.dim = dim
        self.device = torch.device(device)
        self.data = torch.zeros(capacity, dim, device=self.device)
        self.position = 0  # next row to write
        self.size = 0

    def __len__(self) -> int:
        return self.size

    def insert(self, x: torch.Tensor) -> None:
        """Append [B, dim] windows, overwriting the oldest once full (only the last capacity rows if B > capacity)."""
        if x.dim() != 2 or x.shape[1] != self.dim:
            raise ValueError(f"ReplayBuffer.insert expects [B, {self.dim}], got shape {list(x.shape)}.")
        x = x.detach().to(self.device, self.data.dtype)[-self.capacity :]
        rows = (self.position + torch.arange(x.shape[0], device=self.device)) % self.capacity
        self.data[rows] = x
        self.position = (self.position + x.shape[0]) % self.capacity
        self.size = min(self.size + x.shape[0], self.capacity)

    def state_dict(self) -> dict:
        """The filled rows and the write position: a resumed run replays what it had collected."""
        return {"data": self.data[: self.size].clone(), "position": self.position, "size": self.size}

    def load_state_dict(self, state: dict) -> None:
        size = int(state["size"])
        if state["data"].shape != (size, self.dim) or size > self.capacity:
            raise ValueError(f"Replay buffer state of {list(state['data'].shape)} windows does not fit capacity "
                             f"{self.capacity} x dim {self.dim}.")
        self.data[:size] = state["data"].to(self.device)
        self.position, self.size = int(state["position"]), size

    def sample(self, n: int, generator: torch.Generator | None = None) -> torch.Tensor:
        """n stored windows drawn uniformly with replacement, [n, dim]."""
        if self.size == 0:
            raise ValueError("Cannot sample from an empty ReplayBuffer; insert policy windows first.")
        draw_device = generator.device if generator is not None else self.device
        rows = torch.randint(0, self.size, (n,), generator=generator, device=draw_device).to(self.device)
        return self.data[rows]
