import pytest
import torch

from pchc_rsl.algorithms import MultiCriticPPO
from pchc_rsl.training.build import make_runner


@pytest.fixture
def alg(toy_cfg):
    return make_runner(toy_cfg).alg


def fill_storage(alg, gen, preference):
    """Random rewards, values, dones and the given preference in every stored transition."""
    st = alg.storage
    T, N, K = st.rewards.shape
    st.rewards[:] = torch.randn(T, N, K, generator=gen)
    st.values[:] = torch.randn(T, N, K, generator=gen)
    st.dones[:] = (torch.rand(T, N, 1, generator=gen) < 0.15).byte()
    st.observations["preference"][:] = preference
    st.step = T


def reference_gae(rewards, values, dones, last_values, gamma, lam):
    """Plain Python GAE for one env and one critic."""
    T = len(rewards)
    advantages = [0.0] * T
    next_advantage = 0.0
    for t in reversed(range(T)):
        next_value = last_values if t == T - 1 else values[t + 1]
        not_done = 1.0 - dones[t]
        delta = rewards[t] + gamma * next_value * not_done - values[t]
        next_advantage = delta + gamma * lam * not_done * next_advantage
        advantages[t] = next_advantage
    return advantages


def test_per_critic_gae_and_combined_advantage_match_a_reference_loop(alg):
    alg.value_normalizer = None  # raw values here; value normalisation has its own test below
    gen = torch.Generator().manual_seed(0)
    st = alg.storage
    T, N, K = st.rewards.shape
    preference = torch.distributions.Dirichlet(torch.ones(2)).sample((T, N))
    fill_storage(alg, gen, preference)
    alg.task_advantage_weight = 0.7
    obs = alg.storage.observations[-1]
    last_values = alg.critic(obs).detach()
    alg.compute_returns(obs)

    raw = torch.zeros(T, N, K)
    for n in range(N):
        for k in range(K):
            raw[:, n, k] = torch.tensor(reference_gae(
                st.rewards[:, n, k].tolist(), st.values[:, n, k].tolist(), st.dones[:, n, 0].float().tolist(),
                last_values[n, k].item(), alg.gamma, alg.lam,
            ))
    torch.testing.assert_close(st.returns, raw + st.values, atol=1e-5, rtol=1e-5)
    normalised = (raw - raw.mean(dim=(0, 1))) / (raw.std(dim=(0, 1)) + 1e-8)
    expected = 0.7 * normalised[..., 0] + preference[..., 0] * normalised[..., 1] + preference[..., 1] * normalised[..., 2]
    torch.testing.assert_close(st.advantages.squeeze(-1), expected, atol=1e-5, rtol=1e-5)


def advantages_with_objective_2_rewards(alg, scale, preference):
    alg.value_normalizer = None  # the running statistics would carry over from one call to the next
    gen = torch.Generator().manual_seed(1)
    T, N, _ = alg.storage.rewards.shape
    fill_storage(alg, gen, preference.expand(T, N, 2))
    alg.storage.rewards[..., 2] *= scale
    obs = alg.storage.observations[-1]
    alg.compute_returns(obs)
    return alg.storage.advantages.clone()


def test_objective_2_rewards_do_not_matter_at_preference_1_0(alg):
    lam = torch.tensor([1.0, 0.0])
    a = advantages_with_objective_2_rewards(alg, 1.0, lam)
    b = advantages_with_objective_2_rewards(alg, -7.0, lam)
    torch.testing.assert_close(a, b)
    # ... and they do at (0.5, 0.5): the test above can fail
    lam = torch.tensor([0.5, 0.5])
    c = advantages_with_objective_2_rewards(alg, 1.0, lam)
    d = advantages_with_objective_2_rewards(alg, -7.0, lam)
    assert (c - d).abs().max() > 0.1


def test_time_outs_bootstrap_every_critic(alg):
    N = alg.storage.num_envs
    obs = alg.storage.observations[0].clone()
    alg.act(obs)
    values = alg.transition.values.clone()
    groups = torch.randn(N, 3)
    time_outs = torch.zeros(N, dtype=torch.bool)
    time_outs[::2] = True
    alg.process_env_step(obs, groups.sum(-1), time_outs, {"reward_groups": groups, "time_outs": time_outs})
    expected = groups + alg.gamma * values * time_outs.unsqueeze(1).float()
    torch.testing.assert_close(alg.storage.rewards[0], expected)


def test_reward_groups_are_required_with_the_right_width(alg):
    obs = alg.storage.observations[0].clone()
    alg.act(obs)
    N = alg.storage.num_envs
    with pytest.raises(KeyError, match="reward_groups"):
        alg.process_env_step(obs, torch.zeros(N), torch.zeros(N, dtype=torch.bool), {})
    alg.act(obs)
    with pytest.raises(ValueError, match="expected"):
        alg.process_env_step(obs, torch.zeros(N), torch.zeros(N, dtype=torch.bool), {"reward_groups": torch.zeros(N, 2)})


def test_per_mini_batch_normalisation_is_refused(alg):
    with pytest.raises(ValueError, match="normalize_advantage_per_mini_batch"):
        MultiCriticPPO(alg.actor, alg.critic, alg.storage, normalize_advantage_per_mini_batch=True)


def test_value_normalisation_predicts_returns_in_running_units_and_is_scale_free(alg):
    gen = torch.Generator().manual_seed(3)
    st = alg.storage
    T, N, K = st.rewards.shape
    fill_storage(alg, gen, torch.tensor([0.5, 0.5]).expand(T, N, 2))
    st.rewards[..., 2] *= 1000.0  # a group on a much larger scale
    st.values[..., 2] *= 1000.0
    raw_values = st.values.clone()
    obs = st.observations[-1]
    # fresh statistics: mean 0, std 1, eps 0.01, so the raw last value is 1.01 times the critic output
    last_values = 1.01 * alg.critic(obs).detach()
    alg.compute_returns(obs)
    returns = torch.zeros(T, N, K)
    for n in range(N):
        for k in range(K):
            returns[:, n, k] = torch.tensor(reference_gae(
                st.rewards[:, n, k].tolist(), raw_values[:, n, k].tolist(), st.dones[:, n, 0].float().tolist(),
                last_values[n, k].item(), alg.gamma, alg.lam,
            )) + raw_values[:, n, k]
    flat = returns.flatten(0, 1)
    mean, std = flat.mean(0), flat.std(0, unbiased=False)
    torch.testing.assert_close(st.returns, (returns - mean) / (std + 0.01), atol=1e-4, rtol=1e-4)
    torch.testing.assert_close(st.values, (raw_values - mean) / (std + 0.01), atol=1e-4, rtol=1e-4)
    # the value targets of the 1000x group are on the same unit scale as the others
    assert 0.5 < st.returns[..., 2].std() < 2.0


def test_a_silent_reward_group_contributes_nothing(alg):
    """A zero task group (or a constant one with only time-outs) has no advantage; a constant with falls does."""
    N = alg.storage.num_envs
    T = alg.storage.num_transitions_per_env
    gen = torch.Generator().manual_seed(5)
    lam = torch.tensor([0.3, 0.7])

    def rollout(task_reward, terminate):
        obs = alg.storage.observations[0].clone()
        obs["preference"][:] = lam
        alg.storage.clear()
        for t in range(T):
            alg.act(obs)
            objectives = torch.randn(N, 2, generator=gen)
            groups = torch.cat([torch.full((N, 1), task_reward), objectives], dim=-1)
            dones = torch.zeros(N, dtype=torch.bool)
            dones[t % N] = terminate
            time_outs = torch.zeros(N, dtype=torch.bool)
            alg.process_env_step(obs, groups.sum(-1), dones, {"reward_groups": groups, "time_outs": time_outs})
        alg.compute_returns(obs)
        return alg.silent_groups_last

    assert rollout(0.0, terminate=True).tolist() == [True, False, False]
    assert rollout(1.0, terminate=False).tolist() == [True, False, False]
    assert rollout(1.0, terminate=True).tolist() == [False, False, False]


def test_silent_task_group_leaves_the_lambda_weighted_objective_advantages(alg):
    alg.value_normalizer = None
    gen = torch.Generator().manual_seed(7)
    st = alg.storage
    T, N, K = st.rewards.shape
    lam = torch.tensor([0.3, 0.7])
    fill_storage(alg, gen, lam.expand(T, N, 2))
    alg.group_min = torch.tensor([0.0, -1.0, -1.0])  # as if the task reward had been 0 at every step
    alg.group_max = torch.tensor([0.0, 1.0, 1.0])
    obs = st.observations[-1]
    alg.compute_returns(obs)
    advantages = st.returns - st.values
    normalised = (advantages - advantages.mean(dim=(0, 1))) / (advantages.std(dim=(0, 1)) + 1e-8)
    expected = 0.3 * normalised[..., 1] + 0.7 * normalised[..., 2]
    torch.testing.assert_close(st.advantages.squeeze(-1), expected, atol=1e-5, rtol=1e-5)


def test_silent_groups_are_decided_over_all_ranks(alg, monkeypatch):
    """This rank saw a zero task reward (silent here); another rank saw it vary and had a fall. Reduced over the
    ranks (min of minima, max of maxima and of terminations), the group is not silent on either rank. The other
    rank is played by a recorder standing in for torch.distributed.all_reduce."""
    alg.group_min[:] = torch.tensor([0.0, -1.0, -2.0])
    alg.group_max[:] = torch.tensor([0.0, 1.0, 2.0])
    alg.terminated_in_rollout = torch.tensor(False)
    assert alg.silent_groups().tolist() == [True, False, False]
    other = {"min": torch.tensor([-0.5, -1.0, -1.0]), "max": torch.tensor([0.5, 0.5, 1.0]), "terminated": 1.0}
    calls = []

    def all_reduce(tensor, op):
        calls.append(op)
        if op == torch.distributed.ReduceOp.MIN:
            tensor.copy_(torch.minimum(tensor, other["min"]))
        elif tensor.dim() == 0:
            tensor.copy_(torch.maximum(tensor, torch.tensor(other["terminated"])))
        else:
            tensor.copy_(torch.maximum(tensor, other["max"]))

    monkeypatch.setattr(torch.distributed, "all_reduce", all_reduce)
    alg.is_multi_gpu = True
    assert alg.silent_groups().tolist() == [False, False, False]
    assert len(calls) == 3
    other.update(min=torch.zeros(3), max=torch.zeros(3), terminated=0.0)  # the other rank silent as well
    alg.group_min[:], alg.group_max[:] = torch.zeros(3), torch.zeros(3)
    assert alg.silent_groups().tolist() == [True, True, True]


def test_each_experts_routing_mass_over_the_rollout_is_logged(alg):
    """PCI's weights depend on lambda alone: the logged mass is the mean Beta routing weight of the stored preferences."""
    from pchc_rsl.preference import routing_weights

    gen = torch.Generator().manual_seed(3)
    T, N, _ = alg.storage.rewards.shape
    preference = torch.distributions.Dirichlet(torch.ones(2)).sample((T, N))
    fill_storage(alg, gen, preference)
    alg.compute_returns(alg.storage.observations[-1])
    head = alg.actor.mlp
    expected = routing_weights(preference.flatten(0, 1), torch.linspace(0, 1, 5), 1.0, 1.0, head.scale).mean(0)
    logged = torch.tensor([alg.return_stats[f"routing_mass/expert_{j}"] for j in range(5)])
    torch.testing.assert_close(logged, expected, atol=1e-5, rtol=1e-5)
    assert f"routing_mass/expert_{5}" not in alg.return_stats


def test_mini_batches_are_rsl_rl_s_from_the_same_random_stream(alg):
    """The storage's generator gathers rows with index_select; rsl-rl's with advanced indexing. From the same seed
    they yield the same rows of every field, in the same order."""
    from rsl_rl.storage import RolloutStorage

    gen = torch.Generator().manual_seed(1)
    st = alg.storage
    fill_storage(alg, gen, torch.tensor([0.3, 0.7]))
    for name in ("actions", "advantages", "returns", "actions_log_prob"):
        getattr(st, name).copy_(torch.randn(getattr(st, name).shape, generator=gen))
    st.distribution_params = tuple(torch.randn(st.actions.shape, generator=gen) for _ in range(2))
    for group in st.observations.keys():
        st.observations[group].copy_(torch.randn(st.observations[group].shape, generator=gen))
    torch.manual_seed(7)
    ours = list(st.mini_batch_generator(4, 2))
    torch.manual_seed(7)
    theirs = list(RolloutStorage.mini_batch_generator(st, 4, 2))
    assert len(ours) == len(theirs) == 8
    for a, b in zip(ours, theirs):
        for field in ("actions", "values", "advantages", "returns", "old_actions_log_prob"):
            assert torch.equal(getattr(a, field), getattr(b, field)), field
        for p, q in zip(a.old_distribution_params, b.old_distribution_params):
            assert torch.equal(p, q)
        assert a.observations.batch_size == b.observations.batch_size
        for group in b.observations.keys():
            assert torch.equal(a.observations[group], b.observations[group]), group
