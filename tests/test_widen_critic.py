import pytest
import torch
from tensordict import TensorDict

from pchc_rsl.modules import PreferenceMLPModel
from pchc_rsl.runners.widen_critic import widen_critic_inputs

N, WIDTH, ADDED = 32, 7, 3


def make_obs(width, preference=True, seed=0):
    gen = torch.Generator().manual_seed(seed)
    groups = {"critic": torch.randn(N, width, generator=gen) * 3 + 1}
    if preference:
        lam = torch.rand(N, 2, generator=gen)
        groups["preference"] = lam / lam.sum(-1, keepdim=True)
    return TensorDict(groups, batch_size=[N])


def make_critic(obs, preference=True):
    if preference:
        return PreferenceMLPModel(obs, {"critic": ["critic", "preference"]}, "critic", 3, hidden_dims=[16],
                                  obs_normalization=True)
    from rsl_rl.models import MLPModel

    return MLPModel(obs, {"critic": ["critic"]}, "critic", 3, hidden_dims=[16], obs_normalization=True)


@pytest.mark.parametrize("preference", [True, False])
def test_a_widened_critic_values_every_state_as_the_checkpoints_critic_did(preference):
    """The checkpoint's critic (trained normaliser included) on the old observation, against the widened critic on
    the old observation followed by new inputs of any value."""
    narrow = make_obs(WIDTH, preference)
    old = make_critic(narrow, preference)
    for seed in range(3):
        old.update_normalization(make_obs(WIDTH, preference, seed=seed + 1))
    wide = make_obs(WIDTH + ADDED, preference)
    wide["critic"][:, :WIDTH] = narrow["critic"]
    if preference:
        wide["preference"] = narrow["preference"]
    new = make_critic(wide, preference)
    saved = old.state_dict()
    assert widen_critic_inputs(saved, new) == ADDED
    new.load_state_dict(saved)
    torch.testing.assert_close(new(wide), old(narrow))
    assert torch.equal(new.mlp[0].weight[:, WIDTH:WIDTH + ADDED], torch.zeros(16, ADDED))
    new.mlp[0].weight.data[:, WIDTH:WIDTH + ADDED] = 1.0  # and the new inputs are read once their weights move
    assert not torch.allclose(new(wide), old(narrow))


@pytest.mark.parametrize("other", ["same", "narrower", "other units"])
def test_a_critic_without_added_inputs_is_left_alone_for_loading_to_judge(other):
    obs = make_obs(WIDTH)
    critic = make_critic(obs)
    saved = critic.state_dict()
    before = {k: v.clone() for k, v in saved.items()}
    target = {"same": critic, "narrower": make_critic(make_obs(WIDTH - 2)),
              "other units": PreferenceMLPModel(make_obs(WIDTH + ADDED), {"critic": ["critic", "preference"]},
                                                "critic", 3, hidden_dims=[8], obs_normalization=True)}[other]
    assert widen_critic_inputs(saved, target) == 0
    assert all(torch.equal(saved[k], before[k]) for k in before)
    if other != "same":
        with pytest.raises(RuntimeError, match="size mismatch"):
            target.load_state_dict(saved)
