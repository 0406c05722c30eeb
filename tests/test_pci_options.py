"""The PCI actor's options that keep lambda-routed experts: residual experts on a shared network, a routing floor,
a learned gate on top of the Beta density, and a routing warm-up. Each checked against a hand computation."""

import io

import pytest
import torch

from pchc_rsl.modules import PCIActor
from pchc_rsl.preference import routing_weights
from test_models import GAUSSIAN, GROUPS, HISTORY, N, make_obs

POSITIONS = torch.linspace(0, 1, 5)


def expert_outputs(head, features):
    """[E, N, out] each expert by hand: one hidden ELU layer."""
    outputs = []
    for j in range(head.experts.weights[0].shape[0]):
        h = torch.nn.functional.elu(features @ head.experts.weights[0][j] + head.experts.biases[0][j])
        outputs.append(h @ head.experts.weights[1][j] + head.experts.biases[1][j])
    return torch.stack(outputs)


def actor_with(**options):
    return PCIActor(make_obs(), GROUPS, "actor", 3, hidden_dims=[16], history_length=HISTORY, distribution_cfg=GAUSSIAN,
                    routing_scale=4.0, **options)


def test_residual_experts_start_as_the_shared_network_and_add_their_routed_corrections():
    obs = make_obs()
    actor = actor_with(residual_experts=True)
    head = actor.mlp
    features = head.features(actor.get_latent(obs))
    shared = torch.nn.functional.elu(features @ head.shared.weights[0][0] + head.shared.biases[0][0])
    shared = shared @ head.shared.weights[1][0] + head.shared.biases[1][0]
    torch.testing.assert_close(actor(obs), shared)  # every correction is zero at the start
    with torch.no_grad():
        for w in (*head.experts.weights, *head.experts.biases):
            w.normal_()
    weights = routing_weights(obs["preference"], POSITIONS, 1.0, 1.0, 4.0)
    expected = shared + torch.einsum("ne,eno->no", weights, expert_outputs(head, features))
    torch.testing.assert_close(actor(obs), expected, atol=1e-4, rtol=1e-4)


def test_a_routing_floor_gives_every_expert_its_share():
    obs = make_obs()
    actor = actor_with(routing_floor=0.05)
    weights = routing_weights(obs["preference"], POSITIONS, 1.0, 1.0, 4.0)
    expected = 0.05 + 0.75 * weights
    torch.testing.assert_close(actor.expert_weights(obs), expected)
    assert actor.expert_weights(obs).min() >= 0.05 and torch.allclose(expected.sum(-1), torch.ones(N))
    features = actor.mlp.features(actor.get_latent(obs))
    mixed = torch.einsum("ne,eno->no", expected, expert_outputs(actor.mlp, features))
    torch.testing.assert_close(actor(obs), mixed, atol=1e-5, rtol=1e-5)
    with pytest.raises(ValueError, match="routing_floor"):
        actor_with(routing_floor=0.2)


def test_a_prior_gate_starts_as_exact_pci_and_then_corrects_the_beta_density():
    obs = make_obs()
    actor = actor_with(prior_gate_hidden_dims=[8])
    prior = routing_weights(obs["preference"], POSITIONS, 1.0, 1.0, 4.0)
    torch.testing.assert_close(actor.expert_weights(obs), prior)
    with torch.no_grad():
        actor.mlp.gate[-1].bias.copy_(torch.tensor([1.0, 0.0, 0.0, 0.0, -1.0]))
    corrected = prior * torch.tensor([torch.e, 1.0, 1.0, 1.0, 1 / torch.e])
    corrected = corrected / corrected.sum(-1, keepdim=True)
    torch.testing.assert_close(actor.expert_weights(obs), corrected)
    features = actor.mlp.features(actor.get_latent(obs))
    mixed = torch.einsum("ne,eno->no", corrected, expert_outputs(actor.mlp, features))
    torch.testing.assert_close(actor(obs), mixed, atol=1e-5, rtol=1e-5)


def test_the_routing_warms_up_from_even_to_its_scale_and_the_clock_is_saved():
    obs = make_obs()
    actor = actor_with(routing_warmup_updates=4)
    torch.testing.assert_close(actor.expert_weights(obs), torch.full((N, 5), 0.2))  # s = 0: every expert alike
    actor.advance_schedule()
    torch.testing.assert_close(actor.expert_weights(obs), routing_weights(obs["preference"], POSITIONS, 1.0, 1.0, 1.0))
    for _ in range(10):
        actor.advance_schedule()
    torch.testing.assert_close(actor.expert_weights(obs), routing_weights(obs["preference"], POSITIONS, 1.0, 1.0, 4.0))
    buffer = io.BytesIO()
    torch.save(actor.state_dict(), buffer)
    buffer.seek(0)
    resumed = actor_with(routing_warmup_updates=4)
    resumed.load_state_dict(torch.load(buffer, weights_only=True))
    assert int(resumed.mlp.updates) == 11
    # without the options the actor's state dict is the paper's PCI actor's: older checkpoints load
    assert set(actor_with().state_dict()) == set(PCIActor(make_obs(), GROUPS, "actor", 3, hidden_dims=[16],
                                                          history_length=HISTORY,
                                                          distribution_cfg=GAUSSIAN).state_dict())


def test_multi_critic_ppo_advances_the_actors_schedule_once_per_update():
    from pchc_rsl.algorithms.multi_critic_ppo import MultiCriticPPO

    calls = []

    class Probe:
        def advance_schedule(self):
            calls.append(1)

    alg = MultiCriticPPO.__new__(MultiCriticPPO)
    alg.actor, alg.amp, alg.return_stats = Probe(), None, {}
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("rsl_rl.algorithms.PPO.update", lambda self: {})
        alg.update()
        alg.update()
    assert calls == [1, 1]


@pytest.mark.parametrize("options", [{"residual_experts": True}, {"routing_floor": 0.05},
                                     {"prior_gate_hidden_dims": [8]}, {"routing_warmup_updates": 3}])
def test_each_option_exports_to_onnx_and_matches_torch(options, tmp_path):
    onnxruntime = pytest.importorskip("onnxruntime")
    actor = actor_with(**options)
    with torch.no_grad():
        for p in actor.parameters():
            p.add_(0.1 * torch.randn_like(p))
    actor.advance_schedule()
    export = actor.as_onnx()
    path = tmp_path / "actor.onnx"
    obs, preference = export.get_dummy_inputs()
    obs = torch.randn(4, obs.shape[1])
    preference = torch.tensor([[1.0, 0.0], [0.7, 0.3], [0.2, 0.8], [0.0, 1.0]])
    torch.onnx.export(export, (obs, preference), str(path), input_names=["obs", "preference"],
                      output_names=["actions"], dynamo=False)
    session = onnxruntime.InferenceSession(str(path))
    got = session.run(None, {"obs": obs.numpy(), "preference": preference.numpy()})[0]
    torch.testing.assert_close(torch.from_numpy(got), export(obs, preference), atol=1e-5, rtol=1e-4)
