import pytest
import torch

from test_g1_env import pytestmark  # noqa: F401  (skip without the G1 model)

from pchc_rsl.configs import task_config
from pchc_rsl.envs.g1.fall_recovery import host_success, standing_phase


def make_env(num_envs=3, **overrides):
    from pchc_rsl.training.build import make_env as build

    cfg = task_config("g1-fall-recovery-fast")
    cfg.num_envs = num_envs
    for key, value in overrides.items():
        setattr(cfg.env, key, value)
    return build(cfg)


def test_episodes_start_prone_or_supine():
    env = make_env()
    assert env.num_actions == 23
    # face down: the body's forward axis points at the floor, so gravity in the base frame is +x
    torch.testing.assert_close(env.robot.projected_gravity, torch.tensor([[1.0, 0.0, 0.0]]).expand(3, 3), atol=1e-5, rtol=0)
    assert (env.robot.base_pos[:, 2] == pytest.approx(0.3))
    supine = make_env(supine_probability=1.0)
    torch.testing.assert_close(supine.robot.projected_gravity, torch.tensor([[-1.0, 0.0, 0.0]]).expand(3, 3), atol=1e-5, rtol=0)


def test_energy_reward_equals_a_hand_computation():
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_env(num_envs=1)
    tau = torch.tensor([[[2.0, -3.0] + [0.0] * 21, [1.0, 1.0] + [0.0] * 21]])  # [1, K=2, 23]
    dq = torch.tensor([[[0.5, 2.0] + [0.0] * 21, [-1.0, 0.0] + [0.0] * 21]])
    env.robot.torques_substeps, env.robot.joint_vel_substeps = tau, dq
    k_tau, k_p = 0.1, 0.01
    substep_1 = -k_tau * (4 + 9) - k_p * (0.5 * 2 + 2 * 3)
    substep_2 = -k_tau * (1 + 1) - k_p * (1 * 1 + 0 * 1)
    assert g1_rewards.energy(env, k_tau, k_p).item() == pytest.approx((substep_1 + substep_2) / 2)


def test_phase_split_and_success_rule_on_scripted_heights():
    rises_and_stays = torch.tensor([0.2, 0.4, 0.71, 0.6, 0.55, 0.72])
    assert standing_phase(rises_and_stays).tolist() == [False, False, True, True, True, True]
    assert host_success(rises_and_stays)
    falls_again = torch.tensor([0.2, 0.75, 0.74, 0.45, 0.8])
    assert not host_success(falls_again)
    never_up = torch.tensor([0.2, 0.3, 0.69, 0.1])
    assert not standing_phase(never_up).any() and not host_success(never_up)
    low_before_standing_is_fine = torch.tensor([0.45, 0.1, 0.9])
    assert host_success(low_before_standing_is_fine)


def test_env_tracks_success_like_the_rule():
    env = make_env(num_envs=3)
    trajectories = torch.tensor([[0.2, 0.75, 0.6, 0.72], [0.2, 0.75, 0.45, 0.8], [0.2, 0.3, 0.4, 0.3]])
    for t in range(trajectories.shape[1]):
        env.robot.base_pos = env.robot.base_pos.clone()
        env.robot.base_pos[:, 2] = trajectories[:, t]
        env._after_physics()
    tracked = (env.reached_standing & ~env.fell_after_standing).tolist()
    assert tracked == [host_success(h) for h in trajectories]


def test_curriculum_anneals_eta_and_applies_the_assist():
    env = make_env(num_envs=2, eta_anneal_steps=10)
    assert env.action_scale[0].item() == pytest.approx(1.0)
    for _ in range(10):
        env.step(torch.zeros(2, 23))
    assert env.action_scale[0].item() == pytest.approx(0.25)
    torso = env.model.body("torso_link").id
    assert float(env.physics.body_forces[0, torso, 2]) == pytest.approx(env.cfg.assist_force * env.assist_level)
    evaluation = make_env(num_envs=2, curriculum=False)
    evaluation.step(torch.zeros(2, 23))
    assert evaluation.action_scale[0].item() == pytest.approx(0.25)
    assert float(evaluation.physics.body_forces.max()) == 0.0


def test_assist_is_judged_over_num_envs_ended_episodes_not_each_steps_resets():
    """With terminate_on_fall the failures end one by one and the successes together at the time-out: the share
    must count them all (here 1 of 4 succeeded, below 0.7), not only the last batch (1 of 1)."""
    env = make_env(num_envs=4)
    env.episode_length_buf[:] = 5
    env.reached_standing[:] = True
    env.fell_after_standing[:] = torch.tensor([True, True, True, False])
    for failed in range(3):
        env._update_assist(torch.tensor([failed]))
    env._update_assist(torch.tensor([3]))
    assert env.assist_level == 1.0
    env.fell_after_standing[:] = False
    env._update_assist(torch.arange(4))  # 4 of 4 succeeded: one step lower
    assert env.assist_level == pytest.approx(1.0 - env.cfg.assist_level_step)


@pytest.mark.parametrize("terminate", [False, True])
def test_a_fall_after_standing_ends_the_episode_only_with_terminate_on_fall(terminate):
    env = make_env(num_envs=2, terminate_on_fall=terminate)
    env.reached_standing[0] = True  # env 0 "stood" earlier; both lie at 0.3 m, below the 0.5 m fall height
    _, _, dones, extras = env.step(torch.zeros(2, 23))
    assert dones.tolist() == [terminate, False]
    assert not extras["time_outs"].any()
    assert env.episode_length_buf[0].item() == (0 if terminate else 1)  # a terminated episode restarts


@pytest.mark.parametrize("objective", ["disturbance", "energy"])
def test_fall_cost_charges_an_objective_once_at_the_first_fall_after_standing(objective):
    """fall_cost 2.0: env 0 stood earlier and lies below the fall height, so the objective's group gets 2.0 less at
    the first step (times the term's weight 1) than without the cost, and the same at the next; env 1 never stood,
    so lying costs it nothing."""
    from pchc_rsl.configs.g1_fall_recovery import fall_recovery_rewards

    def groups(fall_cost):
        rewards = fall_recovery_rewards()
        for term in rewards:
            if term.group == objective:
                term.params = {**term.params, "fall_cost": fall_cost}
        env = make_env(num_envs=2, rewards=rewards)
        env.reached_standing[0] = True
        column = env.rewards.index[objective]
        return [env.step(torch.zeros(2, 23))[3]["reward_groups"][:, column] for _ in range(2)]

    (first, second), (first_free, second_free) = groups(2.0), groups(0.0)
    torch.testing.assert_close(first - first_free, torch.tensor([-2.0, 0.0]))
    torch.testing.assert_close(second - second_free, torch.tensor([0.0, 0.0]))
