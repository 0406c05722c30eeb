"""The mirror loss read from PPO's pass equals rsl-rl's second pass: same loss, same gradients, same update."""

import copy

import pytest
import torch

from rsl_rl.extensions import Symmetry

from pchc_rsl.algorithms.mirror_loss import SharedPassSymmetry


@pytest.fixture(scope="module")
def walk_runner():
    from test_g1_env import g1_available

    if not g1_available():
        pytest.skip("the G1 model is not available (set MENAGERIE_ROOT)")
    from pchc_rsl.configs import task_config
    from pchc_rsl.training.build import make_runner

    cfg = task_config("g1-walk-fast")
    cfg.num_envs, cfg.runner.num_steps_per_env = 8, 8
    runner = make_runner(cfg)
    assert isinstance(runner.alg.symmetry, SharedPassSymmetry)
    assert runner.alg.symmetry.use_data_augmentation and runner.alg.symmetry.use_mirror_loss
    runner.alg.train_mode()
    obs = runner.rollout(runner.env.get_observations())
    with torch.inference_mode():
        runner.alg.compute_returns(obs)
    return runner


def augmented_batch(alg):
    batch = next(alg.storage.mini_batch_generator(alg.num_mini_batches, 1))
    size = batch.observations.batch_size[0]
    alg.symmetry.augment_batch(batch, size)
    return batch, size


def test_same_loss_and_gradients_as_rsl_rls_second_pass(walk_runner):
    alg = walk_runner.alg
    ours = alg.symmetry
    theirs = Symmetry(ours.env, ours.data_augmentation_func, ours.use_data_augmentation, ours.use_mirror_loss,
                      ours.mirror_loss_coeff)
    batch, size = augmented_batch(alg)
    params = [p for p in alg.actor.parameters() if p.requires_grad]
    alg.actor(batch.observations, stochastic_output=True)  # PPO's pass
    loss_ours = ours.compute_loss(alg.actor, batch, size)
    grads_ours = torch.autograd.grad(loss_ours, params, allow_unused=True)
    alg.actor(batch.observations, stochastic_output=True)
    loss_theirs = theirs.compute_loss(alg.actor, batch, size)
    grads_theirs = torch.autograd.grad(loss_theirs, params, allow_unused=True)
    assert loss_theirs.item() > 0
    torch.testing.assert_close(loss_ours, loss_theirs, rtol=1e-6, atol=0)
    for a, b in zip(grads_ours, grads_theirs):
        if a is None or b is None:
            assert a is None and b is None
            continue
        torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-7)


def test_a_whole_update_moves_the_weights_as_with_rsl_rls_mirror_loss(walk_runner):
    """Same weights, same rollout, same random streams: one PPO update (3 epochs, mirrored mini-batches)
    each way ends at the same losses and weights (to float rounding, within 1% of each tensor's step). AMP is off here
    (no motion files)."""
    alg = walk_runner.alg
    start, rng, learning_rate = copy.deepcopy(alg.save()), torch.get_rng_state(), alg.learning_rate
    storage, ours = copy.deepcopy(alg.storage), alg.symmetry
    results = []
    for symmetry in (ours, Symmetry(alg.symmetry.env, alg.symmetry.data_augmentation_func, True, True,
                                            alg.symmetry.mirror_loss_coeff)):
        state = copy.deepcopy(start)
        with torch.inference_mode():  # the value normaliser's statistics were made in the rollout's inference mode
            alg.value_normalizer.load_state_dict(state.pop("value_normalizer_state_dict"))
        alg.load(state, None, True)
        alg.storage = copy.deepcopy(storage)
        alg.symmetry, alg.learning_rate = symmetry, learning_rate
        for group in alg.optimizer.param_groups:
            group["lr"] = learning_rate
        torch.set_rng_state(rng)
        losses = alg.update()
        results.append((losses, {k: v.clone() for k, v in alg.actor.state_dict().items()}))
    alg.symmetry = ours
    (losses_ours, actor_ours), (losses_theirs, actor_theirs) = results
    for key in ("surrogate", "value", "symmetry"):
        if key in losses_theirs:
            assert losses_ours[key] == pytest.approx(losses_theirs[key], rel=1e-4, abs=1e-6), key
    # Adam divides each gradient by the root of its second moment, so where a gradient is near zero a difference of
    # float rounding becomes a visible fraction of the learning rate: each tensor is compared against the step it took
    # (a mirror loss computed differently changes the step itself, by the order of the step).
    moved = False
    for name, value in actor_theirs.items():
        before = start["actor_state_dict"].get(name)
        if before is None or not torch.is_floating_point(value):
            torch.testing.assert_close(actor_ours[name], value, msg=name)
            continue
        step = (value - before).abs().max().item()
        assert (actor_ours[name] - value).abs().max().item() <= 1e-2 * step + 1e-7, name
        moved |= step > 0
    assert moved
