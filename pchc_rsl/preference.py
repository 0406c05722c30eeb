"""Preference vectors lambda on the probability simplex, and the PCI routing rule.

A preference lambda in R^m has lambda_i >= 0 and sum_i lambda_i = 1. It weighs the m objectives in the
advantage (MultiCriticPPO) and routes the experts of the PCI actor (``routing_weights``).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import torch

SUM_TOLERANCE = 1e-5
DEFAULT_POSITION_EPS = 0.01
"""Expert positions are evaluated inside [eps, 1 - eps]: see routing_weights."""

DEFAULT_ROUTING_SCALE = 3.0
"""s of the routing rule, from the MO-Gymnasium study (docs/results/mo_study.md); until 2026-11-25 it was 10."""
LEGACY_ROUTING_SCALE = 10.0
"""s of PCI checkpoints whose config does not name routing_scale: they were trained before the default changed."""


def sample_preferences(
    num: int, num_objectives: int, concentration: float = 1.0, generator: torch.Generator | None = None
) -> torch.Tensor:
    """Draw ``num`` preferences from a symmetric Dirichlet(concentration). Returns [num, num_objectives], on the
    generator's device.

    Independent Gamma(concentration) samples divided by their sum are Dirichlet distributed. torch's Gamma sampler
    takes no generator, so the Gamma draws are made here from the generator's own normal and uniform draws
    (``gamma_log_samples``): reproducible from the generator alone, on any device, with no host synchronisation
    (a GPU env resamples preferences at every reset).
    """
    if num_objectives < 2:
        raise ValueError(f"A preference needs at least 2 objectives, got num_objectives={num_objectives}.")
    if concentration <= 0:
        raise ValueError(f"The Dirichlet concentration must be > 0, got {concentration}.")
    return torch.softmax(gamma_log_samples((num, num_objectives), concentration, generator), dim=-1)


def gamma_log_samples(shape: tuple[int, ...], concentration: float, generator: torch.Generator | None = None,
                      rounds: int = 16) -> torch.Tensor:
    """log of Gamma(concentration, 1) samples, by Marsaglia and Tsang's squeeze-free method (ACM TOMS 26(3), 2000),
    vectorised with a fixed number of rejection rounds so that no step waits on the device.

    Each round accepts with probability above 0.95 (concentration >= 1), so 16 rounds leave a sample unaccepted with
    probability below 1e-20; such a sample takes the proposal's centre, a - 1/3. Below 1 the draw is boosted:
    Gamma(a) = Gamma(a + 1) U^(1/a), kept in log space where U^(1/a) would underflow.
    """
    device = generator.device if generator is not None else "cpu"
    a = concentration + 1.0 if concentration < 1 else concentration
    d = a - 1.0 / 3.0
    c = 1.0 / (9.0 * d) ** 0.5
    value = torch.full(shape, d, device=device)
    accepted = torch.zeros(shape, dtype=torch.bool, device=device)
    for _ in range(rounds):
        x = torch.randn(shape, generator=generator, device=device)
        u = torch.rand(shape, generator=generator, device=device)
        v = (1.0 + c * x) ** 3
        ok = (v > 0) & (u.log() < 0.5 * x**2 + d - d * v + d * v.clamp_min(1e-30).log())
        value = torch.where(ok & ~accepted, d * v, value)
        accepted |= ok
    log_value = value.log()
    if concentration < 1:
        u = torch.rand(shape, generator=generator, device=device).clamp_min(torch.finfo(torch.float32).tiny)
        log_value = log_value + u.log() / concentration
    return log_value


def _shown(values) -> str:
    """Numbers as a user typed them (0.3, not float32's 0.30000001192092896)."""
    if isinstance(values, list):
        return "[" + ", ".join(_shown(v) for v in values) + "]"
    return f"{values:.6g}"


def validate_preference(lam: torch.Tensor | Sequence[float], num_objectives: int) -> torch.Tensor:
    """Check that ``lam`` ([m] or [N, m]) lies on the simplex; return it as a float tensor or raise ValueError."""
    t = torch.as_tensor(lam, dtype=torch.float32)
    if t.dim() not in (1, 2) or t.shape[-1] != num_objectives:
        raise ValueError(
            f"A preference has one weight per objective ({num_objectives} here, e.g. "
            f"{_shown([1 / num_objectives] * num_objectives)}), got {t.shape[-1] if t.dim() else 1}: "
            f"{_shown(t.tolist())}."
        )
    if not torch.isfinite(t).all():
        raise ValueError(f"A preference must be finite, got {_shown(t.tolist())} (NaN or inf).")
    if (t < 0).any():
        raise ValueError(f"Preference weights must be >= 0, got {_shown(t.tolist())}.")
    sums = t.sum(dim=-1)
    if ((sums - 1.0).abs() > SUM_TOLERANCE).any():
        raise ValueError(
            f"Preference weights must sum to 1 (within {SUM_TOLERANCE:g}), got a sum of {_shown(sums.tolist())} for "
            f"{_shown(t.tolist())}; divide by the sum to normalise."
        )
    return t


class EnvPreferences:
    """The per-env preferences of a vectorised env: Dirichlet samples at each reset unless held by ``hold``.

    ``values`` ([N, m]) is updated in place, so an env may keep it as its ``preference`` attribute.
    """

    def __init__(self, num_envs: int, num_objectives: int, concentration: float, generator: torch.Generator,
                 device: torch.device | str = "cpu") -> None:
        self.num_envs, self.num_objectives = num_envs, num_objectives
        self.concentration, self.generator = concentration, generator
        self.values = torch.zeros(num_envs, num_objectives, device=device)
        self.held: torch.Tensor | None = None

    def hold(self, lam) -> None:
        """Hold lambda ([m] for all envs, or [N, m]) from now on, also across resets; ``None`` resumes sampling."""
        if lam is None:
            self.held = None
            return
        lam = validate_preference(lam, self.num_objectives).to(self.values.device)
        self.held = lam.expand(self.num_envs, -1).clone()
        self.values[:] = self.held

    def resample_where(self, mask: torch.Tensor) -> None:
        """New preferences where ``mask`` ([N] bool) is set, without turning the mask into indices (no host sync)."""
        fresh = self.held if self.held is not None else sample_preferences(
            self.num_envs, self.num_objectives, self.concentration, self.generator).to(self.values.device)
        self.values.copy_(torch.where(mask.unsqueeze(-1), fresh, self.values))

    def resample(self, env_ids: torch.Tensor | list[int]) -> None:
        """New preferences for these envs: the held ones, or fresh Dirichlet samples."""
        if len(env_ids) == 0:
            return
        if self.held is not None:
            self.values[env_ids] = self.held[env_ids]
        else:
            self.values[env_ids] = sample_preferences(
                len(env_ids), self.num_objectives, self.concentration, self.generator
            ).to(self.values.device)


def simplex_lattice(num_objectives: int, resolution: int) -> torch.Tensor:
    """All points of the simplex whose coordinates are multiples of 1/resolution. Returns [E, m].

    For m = 2 and resolution 4 these are the paper's expert positions x_j = 0, .25, .5, .75, 1 (first coordinate),
    listed in increasing x_j.
    """
    if resolution < 1:
        raise ValueError(f"The lattice resolution must be >= 1, got {resolution}.")
    points = [
        c for c in itertools.product(range(resolution + 1), repeat=num_objectives - 1) if sum(c) <= resolution
    ]
    lattice = torch.tensor([[*c, resolution - sum(c)] for c in points], dtype=torch.float32) / resolution
    return lattice


def expert_positions_on_simplex(positions: torch.Tensor | Sequence, num_objectives: int) -> torch.Tensor:
    """Turn expert positions into points on the simplex, [E, m].

    Two objectives accept scalar positions x_j in [0, 1] (the Beta variable), mapped to (x_j, 1 - x_j).
    """
    p = torch.as_tensor(positions, dtype=torch.float32)
    if p.dim() == 1:
        if num_objectives != 2:
            raise ValueError(
                f"Scalar expert positions only make sense for 2 objectives; with {num_objectives} give [E, "
                f"{num_objectives}] points on the simplex."
            )
        p = torch.stack([p, 1.0 - p], dim=-1)
    if p.dim() != 2 or p.shape[1] != num_objectives:
        raise ValueError(f"Expert positions must be [E] (2 objectives) or [E, {num_objectives}], got {list(p.shape)}.")
    if (p < 0).any() or ((p.sum(-1) - 1).abs() > SUM_TOLERANCE).any():
        raise ValueError(f"Expert positions must lie on the simplex, got {p.tolist()}.")
    return p


def routing_weights(
    lam: torch.Tensor,
    positions: torch.Tensor,
    alpha0: float = 1.0,
    beta0: float | None = None,
    scale: float = DEFAULT_ROUTING_SCALE,
    eps: float = DEFAULT_POSITION_EPS,
) -> torch.Tensor:
    """Normalised density of the preference-parameterised Beta/Dirichlet at the expert positions. Returns [N, E].

    Args:
        lam: [N, m] preferences.
        positions: [E] Beta positions x_j (m = 2) or [E, m] points on the simplex.
        alpha0: base concentration of objective 1 (of every objective when m > 2).
        beta0: base concentration of objective 2 when m = 2 (defaults to alpha0).
        scale: s, how sharply the preference concentrates the density. The default 3 comes from the MO-Gymnasium
            study (docs/results/mo_study.md): against s = 10 it lifted the returns at the end preferences on both
            tasks studied, with hypervolume within the seeds' spread.
        eps: position coordinates are clamped into [eps, 1 - eps].

    Two objectives (the paper): alpha = alpha0 + lam_1 s, beta = beta0 + lam_2 s and
    w_j ∝ x_j^(alpha-1) (1-x_j)^(beta-1) / B(alpha, beta). B cancels when normalising over j, so
        w = softmax_j((alpha - 1) log x_j + (beta - 1) log(1 - x_j)),
    which is exact, stable and exportable (no lgamma). With m objectives the Dirichlet density with
    concentrations c_i = c0_i + lam_i s gives w = softmax_j(sum_i (c_i - 1) log p_ji), equal to the Beta rule
    for m = 2 with p_j = (x_j, 1 - x_j).

    Why the clamp matters: the Beta density at x = 1 is exactly 0 whenever beta > 1, i.e. for every preference but
    the vertex (1, 0); an expert sitting exactly at an end would never be trained and would act only at the vertex.
    Evaluated at 1 - eps, it takes over smoothly near the vertex instead (eps = 0.01, alpha0 = beta0 = 1: weight 0.63
    at lambda = (1, 0), 0.35 at (0.9, 0.1), 0.14 at (0.8, 0.2) with s = 3; 0.94, 0.32 and 0.01 with s = 10).
    """
    m = lam.shape[-1]
    points = expert_positions_on_simplex(positions, m) if positions.dim() == 1 else positions
    points = points.to(lam.device, lam.dtype)
    if m > 2 and beta0 is not None and beta0 != alpha0:
        raise ValueError(f"With {m} objectives every objective uses alpha0; got beta0={beta0} != alpha0={alpha0}.")
    second = alpha0 if beta0 is None else beta0
    # made on the device (a tensor from a Python list would be copied there, with a wait, at every call)
    base = torch.where(torch.arange(m, device=lam.device) == 1, float(second), float(alpha0)).to(lam.dtype)
    concentration = base + lam * scale  # [N, m]
    log_points = points.clamp(eps, 1.0 - eps).log()  # [E, m]
    # log of the unnormalised density, sum_i (c_i - 1) log p_ji: [N, m] @ [m, E]
    return torch.softmax((concentration - 1.0) @ log_points.T, dim=-1)
