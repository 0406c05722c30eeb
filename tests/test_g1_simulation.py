"""Checks of the G1 simulation: lean models, contacts and friction, reset state, rewards and metrics."""

import mujoco
import numpy as np
import pytest
import torch

from test_g1_env import make_walk_env, push_now, pytestmark  # noqa: F401  (skip without the G1 model)

from pchc_rsl.robots.g1.constants import WALK_JOINTS
from pchc_rsl.robots.g1.model import COLLISION_GROUP, build_g1_model


def forward_data(env, i=0):
    """An independent MjData of env i's model and current state, after mj_forward."""
    model = env.physics.models[i]
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, env.physics.state[i], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    mujoco.mj_forward(model, data)
    return model, data


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20


def test_physics_model_has_no_visual_meshes_and_only_collision_geoms_collide():
    physics, visual = build_g1_model(WALK_JOINTS, 0.005), build_g1_model(WALK_JOINTS, 0.005, visual=True)
    assert physics.nmesh == 0 and visual.nmesh > 0
    np.testing.assert_allclose(physics.body_mass, visual.body_mass)
    for model in (physics, visual):
        floor = model.geom("floor").id
        for g in range(model.ngeom):
            collides = model.geom_contype[g] or model.geom_conaffinity[g]
            is_mesh = model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
            if is_mesh or model.geom_group[g] == 2:
                assert not collides, f"visual geom {model.geom(g).name} collides"
            elif g != floor:
                assert model.geom_group[g] == COLLISION_GROUP


def test_standing_at_reset_only_the_sole_boxes_touch_the_floor():
    env = make_walk_env(num_envs=1)
    model, data = forward_data(env)
    soles = {model.geom("left_sole").id, model.geom("right_sole").id}
    floor = model.geom("floor").id
    assert data.ncon > 0
    for c in data.contact[: data.ncon]:
        assert floor in (c.geom1, c.geom2) and {c.geom1, c.geom2} - {floor} <= soles


def test_drawn_floor_friction_is_the_contact_friction():
    env = make_walk_env(num_envs=1)
    model = env.physics.models[0]
    model.geom_friction[model.geom("floor").id, 0] = 0.4  # below the robot geoms' 1.0
    _, data = forward_data(env)
    assert data.ncon > 0
    np.testing.assert_allclose(data.contact.friction[: data.ncon, 0], 0.4)


def test_256_randomised_envs_share_a_bounded_set_of_small_models():
    before = rss_mb()
    env = make_walk_env(num_envs=256)
    grown = rss_mb() - before
    models = {id(m) for m in env.physics.models}
    assert len(models) == env.cfg.randomization.num_model_variants < 256
    frictions = {float(m.geom_friction[m.geom("floor").id, 0]) for m in env.physics.models}
    assert len(frictions) == len(models)  # each variant drew its own
    assert grown < 400, f"building 256 envs grew the process by {grown:.0f} MB (a full model copy is ~71 MB)"


def test_no_touchdown_on_the_first_step_after_a_reset():
    env = make_walk_env(num_envs=4, observation_noise=0.0)
    stand = torch.zeros(4, env.num_actions)
    assert env.feet.contact.all()  # standing: both feet start on the ground
    env.step(stand)
    assert not env.feet.first_contact.any() and (env.feet.stride == 0).all()
    for _ in range(5):
        env.step(stand)
    env.reset(torch.tensor([1, 2]))
    env.step(stand)
    assert not env.feet.first_contact[[1, 2]].any()


def test_diverged_envs_earn_nothing_and_are_counted():
    env = make_walk_env(num_envs=3)
    env.physics.state[0, env.physics.qvel_slice] = 1e4  # diverged physics
    _, reward, dones, extras = env.step(torch.zeros(3, env.num_actions))
    assert dones[0] and reward[0] == 0 and (extras["reward_groups"][0] == 0).all()
    assert extras["log"]["Episode_Termination/unstable_envs"].item() == 1
    assert env.unstable_resets == 1


def test_the_critic_gets_the_actors_history_frames_without_noise():
    env = make_walk_env(num_envs=2, observation_noise=0.0)
    for _ in range(3):
        obs, *_ = env.step(0.3 * torch.ones(2, env.num_actions))
    width = obs["policy"].shape[1]
    torch.testing.assert_close(obs["critic"][:, :width], obs["policy"])
    noisy = make_walk_env(num_envs=2)
    obs, *_ = noisy.step(torch.zeros(2, noisy.num_actions))
    assert not torch.allclose(obs["critic"][:, :width], obs["policy"])  # the actor's frames are noisy


def test_amp_gets_the_window_of_the_episode_that_ended():
    env = make_walk_env(num_envs=2)
    previous = env.get_observations()["amp"]
    env.cfg.termination_height = 10.0  # every env terminates on this step
    obs, _, dones, extras = env.step(torch.zeros(2, env.num_actions))
    assert dones.all()
    lived, joints = extras["amp_observations"], env.num_actions
    torch.testing.assert_close(lived[:, :-joints], previous[:, joints:])  # the lived window, shifted by one step
    assert not torch.allclose(lived, obs["amp"])  # obs already holds the new episode's window


def test_walking_objectives_are_in_the_papers_order():
    env = make_walk_env(num_envs=1)
    assert env.cfg.objective_names == ["disturbance", "stride"]


def test_a_push_cut_short_by_a_fall_counts_with_the_deviation_it_reached():
    env = make_walk_env(num_envs=2, observation_noise=0.0)
    env.commands[:] = 0.0
    push_now(env)
    for _ in range(10):  # 0.2 s into the 1 s window
        env.step(torch.zeros(2, env.num_actions))
    reached = env.pushes.max_deviation.clone()
    assert (reached > 0).all()
    metrics = env.episode_metrics(torch.arange(2))
    torch.testing.assert_close(metrics["push_deviation"], reached)


def test_com_is_the_whole_body_centre_of_mass():
    env = make_walk_env(num_envs=1)
    env.step(0.5 * torch.ones(1, env.num_actions))
    model, data = forward_data(env)
    assert model.body_mass[1] != build_g1_model(WALK_JOINTS, 0.005).body_mass[1]  # a randomised pelvis mass
    com = (data.xipos[1:] * model.body_mass[1:, None]).sum(0) / model.body_mass[1:].sum()  # every body but the world
    np.testing.assert_allclose(env.robot.com_pos[0].numpy(), com, atol=2e-3)  # sensors lag one substep
    assert abs(com[0] - env.robot.base_pos[0, 0].item()) > 1e-3  # not the pelvis


def test_fall_recovery_energy_is_power_per_phase_and_overall_lies_between():
    from test_g1_fall_recovery import make_env

    env = make_env(num_envs=1)
    env.step(torch.zeros(1, env.num_actions))
    dt = env.dt
    sums = env.metrics.sums.sums
    sums["energy_recovery"][:] = 743.0 * 100 * dt  # 100 steps at 743 J/s
    sums["energy_standing"][:] = 417.0 * 300 * dt  # 300 steps at 417 J/s
    sums["steps_recovery"][:], sums["steps_standing"][:] = 100, 300
    m = env.episode_metrics(torch.tensor([0]))
    assert m["energy_recovery"].item() == pytest.approx(743.0, rel=1e-5)
    assert m["energy_standing"].item() == pytest.approx(417.0, rel=1e-5)
    assert m["energy_overall"].item() == pytest.approx((743.0 * 100 + 417.0 * 300) / 400, rel=1e-5)


def test_fall_recovery_evaluation_pushes_wait_for_the_robot_to_stand():
    from test_g1_fall_recovery import make_env

    env = make_env(num_envs=2, curriculum=False, terminate_on_fall=False)  # the fallen robot stays in its episode
    env.cfg.push.only_when_standing = True
    env.pushes.countdown[:] = 1
    for _ in range(20):  # lying on the floor: no push however long
        env.step(torch.zeros(2, env.num_actions))
        assert not env.pushes.active.any()
    env.reached_standing[:] = True  # stood up once, but lies on the floor again (fell): still no push
    env.step(torch.zeros(2, env.num_actions))
    assert not env.pushes.active.any()
    from pchc_rsl.robots.g1.constants import STANDING_HEIGHT

    qpos, qvel = super(type(env), env).initial_state(torch.arange(2))  # standing at the default pose
    assert qpos[0, 2] == STANDING_HEIGHT
    env.physics.set_qpos_qvel(torch.arange(2), qpos, qvel)
    env.robot.read()
    env.step(torch.zeros(2, env.num_actions))
    assert env.pushes.active.all()


def test_fall_recovery_curriculum_travels_with_the_env_state():
    from test_g1_fall_recovery import make_env

    env = make_env(num_envs=2, eta_anneal_steps=10)
    for _ in range(6):
        env.step(torch.zeros(2, env.num_actions))
    env.assist_level = 0.35
    state = env.state_dict()
    fresh = make_env(num_envs=2, eta_anneal_steps=10)
    assert fresh.assist_level == 1.0 and fresh.action_scale[0].item() == pytest.approx(1.0)
    fresh.load_state_dict(state)
    assert fresh.assist_level == 0.35
    assert fresh.action_scale[0].item() == pytest.approx(env.action_scale[0].item())
    assert fresh.global_steps == 6 and fresh.action_scale[0].item() == pytest.approx(1.0 - 0.75 * 0.6)


def test_walking_actions_are_scaled_per_joint_by_effort_over_kp():
    from pchc_rsl.robots.g1.constants import joint_gains, joint_motor

    env = make_walk_env(num_envs=1, action_delay_s=(0.0, 0.0))  # one control for the whole step
    sent = []
    step = env.physics.step
    env.physics.step = lambda ctrl: (sent.append(ctrl.clone()), step(ctrl))[1]
    env.step(torch.ones(1, env.num_actions))
    expected = [0.25 * joint_motor(j).effort_limit / joint_gains(j)[0] for j in env.cfg.joints]
    offsets = sent[0][0].numpy() - env.default_joint_pos.numpy()
    np.testing.assert_allclose(offsets, expected, rtol=1e-5)
    assert offsets.max() == pytest.approx(0.548, abs=1e-3)  # hip pitch/yaw, as in mjlab's G1


def test_fall_recovery_reports_pelvis_and_com_displacement_after_a_push():
    from test_g1_fall_recovery import make_env

    env = make_env(num_envs=2, curriculum=False, observation_noise=0.0)
    push_now(env)
    pelvis0, com0 = env.robot.base_pos[:, :2].clone(), env.robot.com_pos[:, :2].clone()
    pelvis_max, com_max = torch.zeros(2), torch.zeros(2)
    for _ in range(10):  # 0.2 s into the window
        env.step(torch.zeros(2, env.num_actions))
        pelvis_max = torch.maximum(pelvis_max, (env.robot.base_pos[:, :2] - pelvis0).norm(dim=-1))
        com_max = torch.maximum(com_max, (env.robot.com_pos[:, :2] - com0).norm(dim=-1))
    m = env.episode_metrics(torch.arange(2))
    torch.testing.assert_close(m["push_deviation"], pelvis_max)
    torch.testing.assert_close(m["com_displacement"], com_max)
    assert (pelvis_max > 0.01).all() and not torch.allclose(pelvis_max, com_max)
