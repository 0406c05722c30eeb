import copy

import numpy as np
import pytest
import scipy.stats
import torch
from tensordict import TensorDict

from pchc_rsl.modules import GatedMoEActor, PCIActor, PreferenceMLPModel
from pchc_rsl.preference import routing_weights

FRAME, HISTORY, N = 4, 5, 6
GROUPS = {"actor": ["policy", "preference"]}
GAUSSIAN = {"class_name": "rsl_rl.modules:GaussianDistribution", "init_std": 1.0}


def make_obs(n=N, m=2, seed=0):
    gen = torch.Generator().manual_seed(seed)
    lam = torch.rand(n, m, generator=gen)
    return TensorDict(
        {"policy": torch.randn(n, FRAME * (HISTORY + 1), generator=gen), "preference": lam / lam.sum(-1, keepdim=True)},
        batch_size=[n],
    )


@pytest.mark.parametrize("experts_see_preference", [True, False])
def test_pci_actor_mixes_its_experts_with_the_beta_routing_weights(experts_see_preference):
    obs = make_obs()
    actor = PCIActor(obs, GROUPS, "actor", 3, hidden_dims=[16], history_length=HISTORY, history_latent_dim=5,
                     distribution_cfg=GAUSSIAN, routing_scale=7.0, experts_see_preference=experts_see_preference)
    head = actor.mlp
    x = obs["policy"]
    latent = head.encoder(x[:, FRAME:])
    # the paper: each expert sees the current observation, lambda and the history latent
    seen = [x[:, :FRAME], obs["preference"]] if experts_see_preference else [x[:, :FRAME]]
    features = torch.cat([*seen, latent], dim=-1)
    # each expert by hand: one hidden ELU layer
    outputs = []
    for j in range(5):
        h = torch.nn.functional.elu(features @ head.experts.weights[0][j] + head.experts.biases[0][j])
        outputs.append(h @ head.experts.weights[1][j] + head.experts.biases[1][j])
    weights = routing_weights(obs["preference"], torch.linspace(0, 1, 5), 1.0, 1.0, 7.0)
    expected = sum(weights[:, j : j + 1] * outputs[j] for j in range(5))
    torch.testing.assert_close(actor(obs), expected, atol=1e-5, rtol=1e-5)
    assert actor(obs, stochastic_output=True).shape == (N, 3)


def test_pci_actor_at_a_vertex_preference_is_the_vertex_expert():
    obs = make_obs()
    obs["preference"][:] = torch.tensor([1.0, 0.0])
    actor = PCIActor(obs, GROUPS, "actor", 3, hidden_dims=[16], routing_scale=500.0)
    head = actor.mlp
    features = head.features(torch.cat([obs["policy"], obs["preference"]], -1))
    only_last = head.experts(features)[4]  # expert at x = 1
    torch.testing.assert_close(actor(obs), only_last, atol=1e-5, rtol=1e-5)


def test_history_reaches_the_actor_only_through_the_encoder():
    obs = make_obs()
    actor = PCIActor(obs, GROUPS, "actor", 3, hidden_dims=[16])
    changed = obs.clone()
    changed["policy"][:, FRAME:] += 1.0
    assert not torch.allclose(actor(obs), actor(changed))
    with torch.no_grad():
        for p in actor.mlp.encoder.parameters():
            p.zero_()
    torch.testing.assert_close(actor(obs), actor(changed))


def test_preference_is_never_normalised():
    obs = make_obs()
    actor = PCIActor(obs, GROUPS, "actor", 3, hidden_dims=[16], obs_normalization=True)
    assert actor.obs_normalizer.mean.shape[-1] == FRAME * (HISTORY + 1)
    big = obs.clone()
    big["preference"] = big["preference"] * 0 + torch.tensor([0.3, 0.7])
    for _ in range(3):
        actor.update_normalization(big)
    latent = actor.get_latent(big)
    torch.testing.assert_close(latent[:, -2:], big["preference"])


def test_three_objectives_use_the_dirichlet_lattice():
    obs = make_obs(m=3)
    actor = PCIActor(obs, GROUPS, "actor", 2, hidden_dims=[8])
    assert actor.mlp.positions.shape == (6, 3)
    assert actor(obs).shape == (N, 2)


def test_gated_and_plain_ablations_run_and_the_gate_is_learned():
    obs = make_obs()
    gated = GatedMoEActor(obs, GROUPS, "actor", 3, hidden_dims=[16], distribution_cfg=GAUSSIAN)
    plain = PreferenceMLPModel(obs, GROUPS, "actor", 3, hidden_dims=[16], distribution_cfg=GAUSSIAN)
    assert gated(obs).shape == plain(obs).shape == (N, 3)
    assert any("gate" in name for name, _ in gated.named_parameters())


def test_errors_name_the_problem():
    obs = make_obs()
    with pytest.raises(ValueError, match="preference group"):
        PCIActor(obs, {"actor": ["policy"]}, "actor", 3)
    with pytest.raises(ValueError, match="history_length"):
        PCIActor(obs, GROUPS, "actor", 3, history_length=4)


def test_expert_weights_are_the_weights_the_actor_mixes_with():
    obs = make_obs()
    pci = PCIActor(obs, GROUPS, "actor", 3, hidden_dims=[16], history_length=HISTORY, routing_scale=4.0)
    torch.testing.assert_close(pci.expert_weights(obs), routing_weights(obs["preference"], torch.linspace(0, 1, 5),
                                                                        1.0, 1.0, 4.0))
    gated = GatedMoEActor(obs, GROUPS, "actor", 3, hidden_dims=[16], history_length=HISTORY)
    latent = gated.get_latent(obs)
    expected = torch.softmax(gated.mlp.gate(gated.mlp.features(latent)), dim=-1)
    torch.testing.assert_close(gated.expert_weights(obs), expected)
    assert gated.expert_weights(obs).shape == (N, 5)


def test_objective_noise_scales_scale_the_training_noise_by_lambda():
    """Sampled actions around the mean have std = learned std * (lambda . scales); log-probabilities follow scipy's
    normal density with that std, and the deterministic output is untouched."""
    n = 20000
    torch.manual_seed(3)
    obs = make_obs(n=n)
    lam = torch.rand(n, 1)
    obs["preference"] = torch.cat([lam, 1 - lam], dim=-1)
    ours = {"class_name": "pchc_rsl.modules.distribution:GaussianDistribution", "init_std": 0.8}
    actor = PCIActor(obs, GROUPS, "actor", 3, hidden_dims=[16], distribution_cfg=ours,
                     objective_noise_scales=[0.5, 2.0])
    with torch.no_grad():
        actions = actor(obs, stochastic_output=True)
        mean = actor(obs)
    expected_std = 0.8 * (0.5 * lam + 2.0 * (1 - lam))
    z = (actions - mean) / expected_std
    for half in (lam[:, 0] < 0.5, lam[:, 0] >= 0.5):  # each half alone: unscaled noise gives 0.63 and 1.26 there
        assert abs(z[half].std().item() - 1.0) < 0.02 and abs(z[half].mean().item()) < 0.02
    logp = scipy.stats.norm.logpdf(actions.numpy(), mean.numpy(), expected_std.numpy()).sum(-1)
    np.testing.assert_allclose(actor.get_output_log_prob(actions).detach().numpy(), logp, rtol=1e-4, atol=1e-3)
    plain = PCIActor(obs, GROUPS, "actor", 3, hidden_dims=[16], distribution_cfg=ours)
    plain.load_state_dict(actor.state_dict())
    torch.testing.assert_close(plain(obs), mean)


def test_objective_noise_scales_are_checked():
    obs = make_obs()
    ours = {"class_name": "pchc_rsl.modules.distribution:GaussianDistribution"}
    with pytest.raises(ValueError, match="2 positive factors"):
        PCIActor(obs, GROUPS, "actor", 3, distribution_cfg=ours, objective_noise_scales=[1.0])
    with pytest.raises(ValueError, match="scale_std"):
        PCIActor(obs, GROUPS, "actor", 3, distribution_cfg=GAUSSIAN, objective_noise_scales=[1.0, 1.0])


def test_trained_experts_alone_change_and_the_other_end_acts_as_before():
    """Fine-tuning experts 3 and 4 (the (1, 0) side of the lattice) with Adam moves only their weights: the encoder,
    the other experts, the action noise and the normaliser's statistics stay, so at lambda = (0, 1), routed to
    expert 0 alone, the actions are the same to the bit."""
    torch.manual_seed(0)
    obs = make_obs(n=64)
    actor = PCIActor(obs, GROUPS, "actor", 3, hidden_dims=[16], history_length=HISTORY, obs_normalization=True,
                     routing_scale=500.0, distribution_cfg=GAUSSIAN, trained_experts=[3, 4])
    stride_end = obs.clone()
    stride_end["preference"] = torch.tensor([[0.0, 1.0]]).expand(64, 2).clone()
    actor.update_normalization(make_obs(n=64, seed=5))
    with torch.no_grad():
        before_actions = actor(stride_end)
    before = {name: value.clone() for name, value in actor.state_dict().items()}
    optimizer = torch.optim.Adam(actor.parameters(), lr=1e-2)
    for step in range(3):
        actor.update_normalization(make_obs(n=64, seed=10 + step))
        actions = actor(obs, stochastic_output=True)
        loss = (actor(obs) - 1.0).pow(2).mean() - actor.get_output_log_prob(actions.detach()).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    after = actor.state_dict()
    moved = {name for name in before if not torch.equal(before[name], after[name])}
    assert moved == {f"mlp.experts.{kind}.{layer}" for kind in ("weights", "biases") for layer in (0, 1)}
    for layer in (0, 1):
        change = (after[f"mlp.experts.weights.{layer}"] - before[f"mlp.experts.weights.{layer}"]).flatten(1).abs()
        assert torch.all(change[:3].amax(1) == 0) and torch.all(change[3:].amax(1) > 0)
    with torch.no_grad():
        assert torch.equal(actor(stride_end), before_actions)


def test_a_copy_of_an_actor_trains_only_its_trained_experts():
    """A deep copy (an EMA or teacher copy, a copy moved to another device) keeps the frozen experts frozen, with its
    own mask: the original's mask changed afterwards does not reach it."""
    obs = make_obs(n=8)
    actor = PCIActor(obs, GROUPS, "actor", 3, hidden_dims=[16], history_length=HISTORY, trained_experts=[1])
    copied = copy.deepcopy(actor)
    actor.trained_expert_mask.zero_()
    copied(obs).pow(2).sum().backward()
    for parameter in copied.mlp.experts.parameters():
        per_expert = parameter.grad.flatten(1).abs().amax(1)
        assert per_expert[1] > 0 and torch.all(per_expert[[0, 2, 3, 4]] == 0)
    assert all(p.grad is None for p in copied.mlp.encoder.parameters())


def test_trained_experts_are_checked():
    obs = make_obs()
    for bad in ([], [5], [1, 1], [-1]):
        with pytest.raises(ValueError, match=r"distinct expert indices in 0\.\.4"):
            PCIActor(obs, GROUPS, "actor", 3, trained_experts=bad)
