import numpy as np
import pytest
import torch
from scipy import stats

from pchc_rsl.preference import (
    expert_positions_on_simplex,
    routing_weights,
    sample_preferences,
    simplex_lattice,
    validate_preference,
)


def test_samples_lie_on_the_simplex_and_follow_the_dirichlet_mean():
    lam = sample_preferences(20000, 3, concentration=2.0, generator=torch.Generator().manual_seed(0))
    assert lam.shape == (20000, 3)
    assert (lam >= 0).all()
    torch.testing.assert_close(lam.sum(-1), torch.ones(20000))
    # Dirichlet(2, 2, 2): mean 1/3, variance a_i (a0 - a_i) / (a0^2 (a0 + 1)) = 2 * 4 / (36 * 7)
    np.testing.assert_allclose(lam.mean(0).numpy(), 1 / 3, atol=0.01)
    np.testing.assert_allclose(lam.var(0).numpy(), 8 / 252, rtol=0.05)


def test_samples_are_reproducible_with_a_generator():
    a = sample_preferences(5, 2, generator=torch.Generator().manual_seed(3))
    b = sample_preferences(5, 2, generator=torch.Generator().manual_seed(3))
    c = sample_preferences(5, 2, generator=torch.Generator().manual_seed(4))
    assert torch.equal(a, b) and not torch.equal(a, c)


@pytest.mark.parametrize(
    "lam, message",
    [
        ([0.5, 0.5, 0.0], "one weight per objective"),
        ([1.2, -0.2], ">= 0"),
        ([0.5, 0.6], "sum to 1"),
        ([float("nan"), 1.0], "finite"),
        ([float("inf"), 0.0], "finite"),
    ],
)
def test_validate_preference_says_what_is_wrong(lam, message):
    with pytest.raises(ValueError, match=message):
        validate_preference(lam, 2)


def test_validate_preference_accepts_batches_on_the_simplex():
    out = validate_preference([[0.25, 0.75], [1.0, 0.0]], 2)
    assert out.shape == (2, 2)


def test_lattice_gives_the_paper_positions():
    lattice = simplex_lattice(2, 4)
    torch.testing.assert_close(lattice[:, 0], torch.tensor([0.0, 0.25, 0.5, 0.75, 1.0]))
    assert len(simplex_lattice(3, 2)) == 6
    assert len(simplex_lattice(3, 4)) == 15


def scipy_beta_weights(lam, x, alpha0, beta0, scale, eps=0.01):
    x = np.clip(x, eps, 1 - eps)  # the documented clamp of the expert positions
    rows = []
    for l1, l2 in lam:
        density = stats.beta.pdf(x, alpha0 + l1 * scale, beta0 + l2 * scale)
        rows.append(density / density.sum())
    return np.array(rows)


@pytest.mark.parametrize("alpha0, beta0, scale", [(1.0, 1.0, 10.0), (1.0, 1.0, 4.0), (2.0, 3.0, 6.0)])
def test_beta_routing_matches_scipy_including_endpoints(alpha0, beta0, scale):
    x = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    lam = np.array([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5], [0.3, 0.7], [0.9, 0.1]])
    ours = routing_weights(torch.tensor(lam, dtype=torch.float32), torch.tensor(x, dtype=torch.float32),
                           alpha0, beta0, scale)
    np.testing.assert_allclose(ours.numpy(), scipy_beta_weights(lam, x, alpha0, beta0, scale), atol=1e-5)


def test_beta_routing_is_stable_for_sharp_densities():
    w = routing_weights(torch.tensor([[1.0, 0.0], [0.0, 1.0]]), torch.linspace(0, 1, 5), scale=2000.0)
    assert torch.isfinite(w).all()
    torch.testing.assert_close(w, torch.tensor([[0.0, 0, 0, 0, 1], [1, 0, 0, 0, 0]]), atol=1e-6, rtol=0)


def test_end_experts_take_over_near_their_vertex():
    # the weights quoted in the routing_weights docstring
    lam = torch.tensor([[1.0, 0.0], [0.9, 0.1], [0.8, 0.2]])
    w_end = routing_weights(lam, torch.linspace(0, 1, 5), scale=10.0)[:, -1]
    torch.testing.assert_close(w_end, torch.tensor([0.94, 0.32, 0.014]), atol=0.01, rtol=0)


def test_dirichlet_routing_matches_scipy():
    rng = np.random.default_rng(0)
    points = rng.dirichlet([2, 2, 2], size=7)  # interior expert positions
    lam = rng.dirichlet([1, 1, 1], size=6)
    ours = routing_weights(torch.tensor(lam, dtype=torch.float32), torch.tensor(points, dtype=torch.float32),
                           alpha0=1.5, scale=5.0)
    expected = []
    for row in lam:
        density = np.array([stats.dirichlet.pdf(p, 1.5 + 5.0 * row) for p in points])
        expected.append(density / density.sum())
    np.testing.assert_allclose(ours.numpy(), np.array(expected), atol=1e-5)


def test_dirichlet_rule_reduces_to_the_beta_rule_for_two_objectives():
    lam = torch.tensor([[0.2, 0.8], [0.7, 0.3]])
    x = torch.linspace(0, 1, 5)
    beta_rule = routing_weights(lam, x, alpha0=1.5, beta0=1.5, scale=8.0)
    dirichlet_rule = routing_weights(lam, expert_positions_on_simplex(x, 2), alpha0=1.5, scale=8.0)
    torch.testing.assert_close(beta_rule, dirichlet_rule)


@pytest.mark.parametrize("concentration", [0.3, 0.5, 1.0, 2.5])
def test_gamma_draws_follow_scipys_gamma(concentration):
    """The generator-driven Gamma sampler (Marsaglia-Tsang, boosted below 1) against scipy's Gamma CDF."""
    from pchc_rsl.preference import gamma_log_samples

    samples = gamma_log_samples((40000,), concentration, torch.Generator().manual_seed(1)).exp().numpy()
    assert stats.kstest(samples, stats.gamma(concentration).cdf).pvalue > 1e-3


@pytest.mark.parametrize("concentration", [0.5, 2.0])
def test_two_objective_preferences_follow_the_beta_density(concentration):
    """lambda_1 of a symmetric Dirichlet(a, a) is Beta(a, a)."""
    lam = sample_preferences(40000, 2, concentration, generator=torch.Generator().manual_seed(2))
    assert stats.kstest(lam[:, 0].numpy(), stats.beta(concentration, concentration).cdf).pvalue > 1e-3


def test_a_sampler_that_ignores_the_shape_fails_the_beta_test():
    """The KS test above can fail: uniform draws are not Beta(0.5, 0.5)."""
    uniform = torch.rand(40000, generator=torch.Generator().manual_seed(2)).numpy()
    assert stats.kstest(uniform, stats.beta(0.5, 0.5).cdf).pvalue < 1e-6
