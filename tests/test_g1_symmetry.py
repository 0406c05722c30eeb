"""The G1's left-right mirror: its rules against the model's joints, and against the physics itself."""

import numpy as np
import pytest
import torch

from pchc_rsl.robots.g1.symmetry import joint_mirror, mirror_quaternion

pytest.importorskip("mujoco")
from test_g1_env import g1_available, make_walk_env  # noqa: E402


def test_joint_mirror_swaps_sides_and_signs_roll_and_yaw():
    joints = ["left_hip_pitch_joint", "left_hip_roll_joint", "right_hip_pitch_joint", "right_hip_roll_joint",
              "waist_yaw_joint"]
    index, sign = joint_mirror(joints)
    assert index == [2, 3, 0, 1, 4]
    assert sign == [1.0, -1.0, 1.0, -1.0, -1.0]
    with pytest.raises(ValueError, match="no mirror partner"):
        joint_mirror(["left_knee_joint"])


def test_quaternion_mirror_is_the_reflected_rotation():
    """R' = M R M with M = diag(1, -1, 1), computed with MuJoCo's own quaternion-to-matrix conversion."""
    import mujoco

    rng = np.random.default_rng(0)
    m = np.diag([1.0, -1.0, 1.0])
    for _ in range(5):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        r, r_mirror = np.zeros(9), np.zeros(9)
        mujoco.mju_quat2Mat(r, q)
        mujoco.mju_quat2Mat(r_mirror, mirror_quaternion(q))
        np.testing.assert_allclose(r_mirror.reshape(3, 3), m @ r.reshape(3, 3) @ m, atol=1e-12)


needs_g1 = pytest.mark.skipif(not g1_available(), reason="G1 model unavailable (set MENAGERIE_ROOT)")


@needs_g1
def test_model_joint_ranges_are_mirror_images():
    """The sign rule read off the model: the mirror of each joint's range is its partner's range."""
    from pchc_rsl.robots.g1.constants import WALK_HELD_JOINTS, WALK_JOINTS
    from pchc_rsl.robots.g1.model import build_g1_model
    from pchc_rsl.robots.g1.symmetry import mirror_joint_name, mirror_joint_sign

    model = build_g1_model(WALK_JOINTS, held_joints=tuple(WALK_HELD_JOINTS))
    for joint in WALK_JOINTS + WALK_HELD_JOINTS:
        low, high = model.jnt_range[model.joint(joint).id]
        partner = model.jnt_range[model.joint(mirror_joint_name(joint)).id]
        mirrored = sorted([mirror_joint_sign(joint) * low, mirror_joint_sign(joint) * high])
        np.testing.assert_allclose(mirrored, partner, atol=1e-3, err_msg=joint)


@needs_g1
def test_mirror_twice_is_identity_and_keeps_lambda():
    from pchc_rsl.envs.g1.symmetry import augment_with_mirror, mirror_of

    env = make_walk_env(num_envs=4)
    for _ in range(5):
        obs, *_ = env.step(0.3 * torch.randn(4, env.num_actions))
    mirror = mirror_of(env)
    twice = mirror.observations(mirror.observations(obs))
    for group in obs.keys():
        torch.testing.assert_close(twice[group], obs[group], rtol=0, atol=0)
    augmented, actions = augment_with_mirror(env, obs, torch.ones(4, env.num_actions))
    assert augmented.batch_size[0] == 8 and actions.shape == (8, env.num_actions)
    torch.testing.assert_close(augmented["preference"][4:], obs["preference"])
    assert not torch.equal(augmented["policy"][4:], obs["policy"])


@needs_g1
def test_mirrored_start_stepped_with_mirrored_actions_stays_the_mirror():
    """Two robots, one the mirror image of the other, driven by mirrored actions and commands for 1 s of random
    actions: the second one's observation stays the mirror of the first one's. Tolerances: joint positions 0.03 rad,
    gravity in the base frame 0.03, base height 3 mm (measured on the menagerie G1: 0.011 rad at most; contacts make
    velocities drift apart faster, so they are not compared). A wrong sign on any roll or yaw joint, or an unswapped
    pair, is off by tenths of a radian within a few steps."""
    env = make_walk_env(num_envs=2, randomization=_off(), observation_noise=0.0, push=_no_push(),
                        action_delay_s=(0.0, 0.0), command_resample_s=None)
    generator = torch.Generator().manual_seed(0)
    for _ in range(10):
        env.step(0.3 * torch.randn(2, env.num_actions, generator=generator))
    mirror = _make_the_second_robot_the_mirror_of_the_first(env)
    joints = env.num_actions
    for _ in range(50):
        action = 0.5 * torch.randn(1, joints, generator=generator)
        obs, *_ = env.step(torch.cat([action, mirror.action(action)]))
        expected = mirror.observations(obs[0:1])["policy"][0]
        actual = obs["policy"][1]
        torch.testing.assert_close(actual[6:6 + joints], expected[6:6 + joints], rtol=0, atol=0.03)
        torch.testing.assert_close(actual[3:6], expected[3:6], rtol=0, atol=0.03)
        assert abs(env.physics.qpos[0, 2] - env.physics.qpos[1, 2]) < 3e-3
        assert abs(env.physics.qpos[0, 1] + env.physics.qpos[1, 1]) < 3e-3  # mirrored sideways position


def _off():
    from pchc_rsl.envs.g1.config import RandomizationConfig

    return RandomizationConfig(enabled=False)


def _no_push():
    from pchc_rsl.envs.g1.config import PushConfig

    return PushConfig(enabled=False)


@needs_g1
def test_the_holds_state_of_a_mirrored_walker_is_the_mirror():
    """Two robots, one the mirror image of the other, told mirrored commands and driven by mirrored actions for 1 s
    from paths restarted where they stand: the critic's offset from the path, heading error and averaged velocity
    of the second are the mirror of the first's (0.01 m, 0.02 rad, 0.05 m/s; the unmirrored values move by tenths)."""
    env = make_walk_env(num_envs=2, randomization=_off(), observation_noise=0.0, push=_no_push(),
                        action_delay_s=(0.0, 0.0), command_resample_s=None, critic_command_state=True)
    mirror = _make_the_second_robot_the_mirror_of_the_first(env)
    env.command.path.restart(torch.ones(2, dtype=torch.bool), env.robot.base_pos[:, :2], env.robot.yaw)
    env.command.heading_error[:], env.command.velocity_average[:] = 0.0, 0.0
    generator = torch.Generator().manual_seed(1)
    for _ in range(50):
        action = 0.3 * torch.randn(1, env.num_actions, generator=generator)
        obs, *_ = env.step(torch.cat([action, mirror.action(action)]))
    expected = mirror.observations(obs[0:1])["critic"][0, -6:]
    actual = obs["critic"][1, -6:]
    assert obs["critic"][0, -6:].abs().max() > 0.1
    torch.testing.assert_close(actual[:2], expected[:2], rtol=0, atol=0.01)
    torch.testing.assert_close(actual[2:3], expected[2:3], rtol=0, atol=0.02)
    torch.testing.assert_close(actual[3:], expected[3:], rtol=0, atol=0.05)


@needs_g1
def test_the_amp_root_velocity_of_a_mirrored_walker_is_the_mirror():
    """The base velocity in the amp frames (forward, sideways, yaw rate) of the mirrored robot is the mirror of the
    first's at every step of 1 s of mirrored actions. Measured on the menagerie G1: at most 0.008 m/s apart, the yaw
    rate at most 0.13 rad/s (at a peak of 2.7 rad/s over one 20 ms step), 0.001 in the median; unmirrored, the
    sideways part and the yaw rate are 0.31 m/s and 1.0 rad/s apart in the median."""
    env = make_walk_env(num_envs=2, randomization=_off(), observation_noise=0.0, push=_no_push(),
                        action_delay_s=(0.0, 0.0), command_resample_s=None, amp_root_velocity=True)
    mirror = _make_the_second_robot_the_mirror_of_the_first(env)
    generator = torch.Generator().manual_seed(2)
    apart = []
    for _ in range(50):
        action = 0.3 * torch.randn(1, env.num_actions, generator=generator)
        obs, *_ = env.step(torch.cat([action, mirror.action(action)]))
        apart.append((obs["amp"][1, -3:] - mirror.observations(obs[0:1])["amp"][0, -3:]).abs())
    apart = torch.stack(apart)
    assert apart[:, :2].max() < 0.03 and apart[:, 2].max() < 0.2
    assert apart.median(0).values.max() < 0.01
    joints = env.num_actions
    torch.testing.assert_close(obs["amp"][1, -3 - joints:-3], mirror.observations(obs[0:1])["amp"][0, -3 - joints:-3],
                               rtol=0, atol=0.03)


def _make_the_second_robot_the_mirror_of_the_first(env):
    """Env 1 takes the mirror image of env 0's state, command and action buffers; returns the env's mirror."""
    from pchc_rsl.envs.g1.symmetry import mirror_of
    from pchc_rsl.robots.g1.symmetry import mirror_free_state

    qpos, qvel = env.physics.qpos[0].numpy().copy(), env.physics.qvel[0].numpy().copy()
    mirrored_qpos, mirrored_qvel = mirror_free_state(env.model, qpos, qvel)
    env.physics.set_qpos_qvel(torch.tensor([0, 1]), torch.tensor(np.stack([qpos, mirrored_qpos])),
                              torch.tensor(np.stack([qvel, mirrored_qvel])))
    env.robot.read()
    mirror = mirror_of(env)
    env.commands[0] = torch.tensor([0.5, 0.2, 0.3])
    env.commands[1] = torch.tensor([0.5, -0.2, -0.3])
    for buffer in ("actions", "last_actions", "joint_targets"):
        getattr(env, buffer)[1] = mirror.action(getattr(env, buffer)[0])
    env.observations.reset(env, torch.tensor([0, 1]))
    return mirror
