import glob
import math
import os
import subprocess
import sys

import pytest
import torch

from pchc_rsl.configs import task_config

pytest.importorskip("mujoco")


def g1_available() -> bool:
    try:
        from pchc_rsl.robots.g1.model import load_g1_spec

        load_g1_spec()
        return True
    except RuntimeError:
        return False


pytestmark = pytest.mark.skipif(not g1_available(), reason="G1 model unavailable (set MENAGERIE_ROOT)")


def make_walk_env(num_envs=4, seed=0, **env_overrides):
    from pchc_rsl.training.build import make_env

    cfg = task_config("g1-walk-fast")
    cfg.num_envs, cfg.seed = num_envs, seed
    for key, value in env_overrides.items():
        setattr(cfg.env, key, value)
    return make_env(cfg)


def test_models_actuate_the_task_joints():
    from pchc_rsl.robots.g1.constants import FALL_RECOVERY_JOINTS, WALK_JOINTS
    from pchc_rsl.robots.g1.model import build_g1_model

    walk, recovery = build_g1_model(WALK_JOINTS), build_g1_model(FALL_RECOVERY_JOINTS)
    assert (walk.nu, walk.nq, walk.nv) == (20, 27, 26)
    assert (recovery.nu, recovery.nq, recovery.nv) == (23, 30, 29)
    assert [walk.actuator(i).name for i in range(3)] == ["left_hip_pitch", "left_hip_roll", "left_hip_yaw"]
    with pytest.raises(ValueError, match="Unknown G1 joints"):
        build_g1_model(["left_tail_joint"])


def test_missing_model_says_how_to_fix_it_in_one_line(tmp_path):
    code = "from pchc_rsl.robots.g1.model import load_g1_spec\nload_g1_spec()"
    env = {**os.environ, "MENAGERIE_ROOT": str(tmp_path)}
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert result.returncode != 0 and "MENAGERIE_ROOT" in result.stderr
    # every G1 command: one line naming the variable, no traceback
    walk = os.path.join(os.path.dirname(__file__), "..", "policies", "g1_walk.pt")
    for command in (["pchc_rsl.cli.train", "--task", "g1-walk-fast", "--log-dir", str(tmp_path / "run")],
                    ["pchc_rsl.cli.eval", walk, "--output", str(tmp_path / "eval")],
                    ["pchc_rsl.cli.play", walk, "--video", str(tmp_path / "v.mp4")]):
        result = subprocess.run([sys.executable, "-m", *command], capture_output=True, text=True, env=env)
        assert result.returncode != 0 and "Traceback" not in result.stderr, command
        assert len(result.stderr.strip().splitlines()) == 1 and "MENAGERIE_ROOT" in result.stderr, result.stderr


def test_observation_shapes():
    env = make_walk_env()
    obs = env.get_observations()
    frame = 3 + 3 + 20 * 3 + 1 + 3  # ang vel, gravity, q, dq, last action, eta, command
    assert obs["policy"].shape == (4, 6 * frame)
    assert obs["preference"].shape == (4, 2)
    torch.testing.assert_close(obs["preference"].sum(-1), torch.ones(4))
    assert obs["critic"].shape[0] == 4
    o, r, d, extras = env.step(torch.zeros(4, 20))
    assert extras["reward_groups"].shape == (4, 3) and r.shape == (4,) and d.shape == (4,)


def test_touchdown_step_is_measured_from_the_feet_last_contact_in_the_heading_frame():
    env = make_walk_env(num_envs=1)
    K = env.cfg.decimation
    feet = env.feet
    feet.contact[:] = torch.tensor([[False, True]])  # left foot in the air, right on the ground
    feet.last_contact_pos[:] = torch.tensor([[[0.0, 0.0], [0.2, -0.1]]])
    foot_pos = torch.tensor([[[0.3, 0.4, 0.03], [0.2, -0.1, 0.03]]])
    touch = torch.zeros(1, K, 2)
    touch[0, K // 2 :, 0] = 50.0  # left touches down mid-step
    touch[0, :, 1] = 200.0  # right stays down
    heading = torch.tensor([[0.0, 1.0]])  # the base faces +y: forward is +y, lateral (left) is -x
    feet.update(touch, foot_pos, heading)
    assert feet.first_contact.tolist() == [[True, False]]
    assert feet.stride[0, 0].item() == pytest.approx(0.5)  # |(0.3, 0.4) - (0, 0)|
    torch.testing.assert_close(feet.step_vector[0, 0], torch.tensor([0.4, -0.3]))
    torch.testing.assert_close(feet.stance_step[0, 0], torch.tensor([0.4, -0.3]))
    # the touchdown point becomes the new last-contact point; the step is held while that stance lasts
    torch.testing.assert_close(feet.last_contact_pos[0, 0], torch.tensor([0.3, 0.4]))
    feet.update(touch, foot_pos, heading)
    assert feet.stride[0, 0].item() == 0.0 and (feet.step_vector == 0).all()
    torch.testing.assert_close(feet.stance_step[0, 0], torch.tensor([0.4, -0.3]))
    feet.update(torch.zeros(1, K, 2), foot_pos, heading)  # both feet lift off
    assert (feet.stance_step == 0).all()


def scripted_walk(env, stride: float, speed: float, duration: float, duty: float = 0.6):
    """Walk both feet at ``speed`` along +x with strides of ``stride`` (each foot on the ground ``duty`` of its
    cycle, the feet half a cycle apart), feeding FootContacts the sole forces and positions step by step; returns
    the stride reward summed over the walk (per second of reward weight: times dt)."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    dt, K = env.dt, env.cfg.decimation
    period = stride / speed
    env.commands[:] = torch.tensor([speed, 0.0, 0.0])
    feet = env.feet
    feet.reset(torch.tensor([0]), torch.full((1, K, 2), 100.0), torch.zeros(1, 2, 3), 0.03)
    total = 0.0
    for i in range(1, int(round(duration / dt)) + 1):
        t = i * dt
        touch, pos = torch.zeros(1, K, 2), torch.zeros(1, 2, 3)
        for foot, offset in enumerate((0.0, 0.5)):
            phase = (t / period + offset) % 1.0
            cycles = math.floor(t / period + offset)
            stance = phase < duty
            touch[0, :, foot] = 100.0 if stance else 0.0
            # on the ground the foot stays where it landed; in the air it moves a whole stride ahead
            landed = cycles * stride
            pos[0, foot, 0] = landed if stance else landed + stride * (phase - duty) / (1 - duty)
        feet.update(touch, pos, torch.tensor([[1.0, 0.0]]))
        total += float(g1_rewards.stride(env)) * dt
    return total


def test_stride_reward_pays_longer_steps_at_the_same_speed():
    """The docstring's worked example: at 0.5 m/s for 10 s, duty 0.6, strides of 0.8 m earn twice what strides of
    0.4 m earn (about 0.6 x L x 10 s per foot); paying each touchdown its step would earn both the same travel."""
    env = make_walk_env(num_envs=1)
    short = scripted_walk(env, stride=0.4, speed=0.5, duration=10.0)
    long = scripted_walk(env, stride=0.8, speed=0.5, duration=10.0)
    assert short == pytest.approx(2 * 0.6 * 0.4 * 10.0, rel=0.1)
    assert long == pytest.approx(2 * 0.6 * 0.8 * 10.0, rel=0.1)
    assert long / short == pytest.approx(2.0, rel=0.1)


def test_stride_reward_pays_nothing_sideways_backwards_or_when_told_to_stand():
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=3)
    env.feet.contact[:] = True
    env.feet.stance_step[:] = torch.tensor([[[0.3, 0.0], [0.0, 0.0]], [[0.0, 0.2], [-0.2, 0.0]], [[0.3, 0.0], [0.2, 0]]])
    env.commands[:] = torch.tensor([[0.5, 0, 0], [0.5, 0, 0], [0.0, 0, 0]])
    torch.testing.assert_close(g1_rewards.stride(env), torch.tensor([0.3, 0.0, 0.0]))
    # the paper's plain norm, on request
    torch.testing.assert_close(g1_rewards.stride(env, along_heading=False), torch.tensor([0.3, 0.4, 0.0]))


def test_stride_reward_gated_by_speed_pays_nothing_for_walking_faster():
    """speed_std: a 0.3 m step at the commanded 0.5 m/s pays 0.3; the same step at 1.0 m/s pays
    0.3 exp(-0.5^2 / 0.25^2) = 0.3 e^-4; at 0.6 m/s, 0.3 e^-0.16."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=3)
    env.feet.stance_step[:] = torch.tensor([[0.3, 0.0], [0.0, 0.0]])
    env.commands[:] = torch.tensor([0.5, 0.0, 0.0])
    env.robot.base_lin_vel = torch.tensor([[0.5, 0.0, 0.0], [1.0, 0.0, 0.0], [0.6, 0.0, 0.0]])
    expected = torch.tensor([0.3, 0.3 * math.exp(-4.0), 0.3 * math.exp(-0.16)])
    torch.testing.assert_close(g1_rewards.stride(env, speed_std=0.25), expected)
    torch.testing.assert_close(g1_rewards.stride(env), torch.full((3,), 0.3))  # ungated, as before


def test_stride_reward_at_command_speed_pays_a_faster_walk_as_the_commanded_one():
    """at_command_speed: a 0.3 m step walked at twice the commanded 0.5 m/s pays the 0.15 m its cadence makes at
    0.5 m/s; a slower walk pays its whole step; told 0.3 m/s sideways and stepping 0.2 m left at 0.6 m/s, 0.1."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=4)
    env.feet.stance_step[:] = torch.tensor([[[0.3, 0.0], [0.0, 0.0]], [[0.3, 0.0], [0.0, 0.0]],
                                            [[0.3, 0.0], [0.0, 0.0]], [[0.0, 0.2], [0.0, 0.0]]])
    env.commands[:] = torch.tensor([[0.5, 0, 0], [0.5, 0, 0], [0.5, 0, 0], [0.0, 0.3, 0]])
    env.robot.base_lin_vel = torch.tensor([[0.5, 0.0, 0.0], [1.0, 0.0, 0.0], [0.4, 0.0, 0.0], [0.0, 0.6, 0.0]])
    reward = g1_rewards.stride(env, along_command=True, at_command_speed=True)
    torch.testing.assert_close(reward, torch.tensor([0.3, 0.15, 0.3, 0.1]))
    gated = g1_rewards.stride(env, along_command=True, at_command_speed=True, speed_std=0.25)
    torch.testing.assert_close(gated[1], torch.tensor(0.15 * math.exp(-4.0)))


def test_stride_reward_gated_by_average_speed_reads_the_averaged_velocity_not_the_instantaneous_one():
    """average_speed_std 0.1: a 0.3 m step pays 0.3 when the averaged velocity is the commanded 0.5 m/s, whatever the
    instantaneous velocity (0.8 m/s here); averaged 0.6 m/s, 0.3 e^-1; averaged 0.5 m/s ahead and 0.2 m/s aside,
    0.3 e^-4."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=3)
    env.feet.stance_step[:] = torch.tensor([[0.3, 0.0], [0.0, 0.0]])
    env.commands[:] = torch.tensor([0.5, 0.0, 0.0])
    env.robot.base_lin_vel = torch.tensor([[0.8, 0.0, 0.0], [0.5, 0.0, 0.0], [0.5, 0.0, 0.0]])
    env.command.velocity_average = torch.tensor([[0.5, 0.0, 0.0], [0.6, 0.0, 0.0], [0.5, 0.2, 0.0]])
    expected = torch.tensor([0.3, 0.3 * math.exp(-1.0), 0.3 * math.exp(-4.0)])
    torch.testing.assert_close(g1_rewards.stride(env, average_speed_std=0.1), expected)


def test_stride_reward_at_the_commanded_length_scales_slower_and_faster_steps_alike():
    """Told 0.5 m/s, a 0.3 m step pays 0.3 x 0.5 / v for the averaged velocity v along the command: 0.3 at 0.5 m/s,
    0.25 at 0.6, 0.375 at 0.4, and 0.6 (at most twice) when standing still; told 0.3 m/s aside, a 0.2 m step aside at
    0.2 m/s pays 0.3."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=5)
    env.feet.stance_step[:] = torch.tensor([[[0.3, 0.0], [0.0, 0.0]]] * 4 + [[[0.0, 0.2], [0.0, 0.0]]])
    env.commands[:] = torch.tensor([[0.5, 0, 0]] * 4 + [[0.0, 0.3, 0]])
    env.robot.base_lin_vel = torch.full((5, 3), 0.5)  # the instantaneous velocity is not read
    env.command.velocity_average = torch.tensor([[0.5, 0.0, 0.0], [0.6, 0.1, 0.0], [0.4, 0.0, 0.0], [0.0, 0.0, 0.0],
                                         [0.0, 0.2, 0.0]])
    reward = g1_rewards.stride(env, along_command=True, commanded_length=True)
    torch.testing.assert_close(reward, torch.tensor([0.3, 0.25, 0.375, 0.6, 0.3]))


def test_stride_reward_gated_by_path_pays_less_the_further_the_base_is_from_its_commanded_path():
    """path_std 0.25: a 0.3 m step on the path pays 0.3; 0.25 m ahead of it, 0.3 e^-1; 0.5 m aside, 0.3 e^-4."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=3)
    env.feet.stance_step[:] = torch.tensor([[0.3, 0.0], [0.0, 0.0]])
    env.commands[:] = torch.tensor([0.5, 0.0, 0.0])
    env.command.path.position = torch.tensor([[1.0, 2.0], [1.0, 2.0], [1.0, 2.0]])
    base_pos = env.robot.base_pos.clone()
    base_pos[:, :2] = torch.tensor([[1.0, 2.0], [1.25, 2.0], [1.0, 2.5]])
    env.robot.base_pos = base_pos
    expected = torch.tensor([0.3, 0.3 * math.exp(-1.0), 0.3 * math.exp(-4.0)])
    torch.testing.assert_close(g1_rewards.stride(env, path_std=0.25), expected)


def test_stride_reward_gated_by_height_pays_less_the_lower_the_pelvis():
    """height_std 0.08 below a target of 0.74 m: a 0.3 m step pays 0.3 with the pelvis at 0.78 or 0.74 m,
    0.3 e^-0.25 at 0.70 m and 0.3 e^-2.25 at 0.62 m."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=4)
    env.feet.stance_step[:] = torch.tensor([[0.3, 0.0], [0.0, 0.0]])
    env.commands[:] = torch.tensor([0.5, 0.0, 0.0])
    base_pos = env.robot.base_pos.clone()
    base_pos[:, 2] = torch.tensor([0.78, 0.74, 0.70, 0.62])
    env.robot.base_pos = base_pos
    expected = torch.tensor([0.3, 0.3, 0.3 * math.exp(-0.25), 0.3 * math.exp(-2.25)])
    torch.testing.assert_close(g1_rewards.stride(env, height_target=0.74, height_std=0.08), expected)
    torch.testing.assert_close(g1_rewards.stride(env), torch.full((4,), 0.3))  # off by default


def test_action_delay_holds_the_previous_target_for_the_first_substeps():
    """env.action_delay_s (0.01, 0.01) on the fast physics (5 ms substeps): 2 of the 4 substeps hold the old
    target; the physics receives one control per substep."""
    env = make_walk_env(num_envs=2, action_delay_s=(0.01, 0.01))
    assert env.action_delay.substeps.tolist() == [2, 2]
    previous = env.joint_targets.clone()
    target = previous + 0.1
    control = env.action_delay.control(target, previous)
    assert control.shape == (2, env.cfg.decimation, env.num_actions)
    torch.testing.assert_close(control[:, :2], previous.unsqueeze(1).expand(2, 2, -1))
    torch.testing.assert_close(control[:, 2:], target.unsqueeze(1).expand(2, 2, -1))
    env.step(torch.ones(2, env.num_actions))
    expected = env.default_joint_pos + env.action_scale * env.joint_action_weights * 1.0
    torch.testing.assert_close(env.joint_targets, expected.expand(2, -1))
    with pytest.raises(ValueError, match="one policy step"):
        make_walk_env(num_envs=1, action_delay_s=(0.0, 0.05))


def test_action_delay_is_seen_in_the_physics():
    """A delayed env's joints answer a new target later than an undelayed one's: after one step the undelayed
    knee has moved further towards it (same start, same action)."""
    env = make_walk_env(num_envs=2, action_delay_s=(0.0, 0.02), initial_joint_noise=0.0)
    env.action_delay.substeps[:] = torch.tensor([0, 4])  # env 1 holds the old target for the whole step
    knee = env.cfg.joints.index("left_knee_joint")
    start = env.robot.joint_pos[:, knee].clone()
    action = torch.zeros(2, env.num_actions)
    action[:, knee] = 2.0
    env.step(action)
    moved = env.robot.joint_pos[:, knee] - start
    assert moved[0] > 0.05 and abs(moved[1]) < 0.5 * moved[0]


def test_zero_command_share():
    env = make_walk_env(num_envs=200, zero_command_probability=0.5)
    standing = (env.commands == 0).all(-1).float().mean().item()
    assert 0.35 < standing < 0.65


def push_now(env):
    """Push every env at once (as the countdown running out would); returns the velocity kick [N, 2]."""
    before = env.physics.qvel[:, :2].float()
    env.pushes.countdown[:] = 1
    env.pushes.apply(env.physics, env.robot, env.commands)
    return env.physics.qvel[:, :2].float() - before


def test_push_records_direction_and_gives_r_disturb():
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=3)
    env.commands[:] = 0.0
    kick = push_now(env)
    speed = kick.norm(dim=-1)
    low, high = env.cfg.push.velocity
    assert ((speed >= low - 1e-6) & (speed <= high + 1e-6)).all()
    pushes, robot = env.pushes, env.robot
    torch.testing.assert_close(kick / speed.unsqueeze(-1), pushes.direction)
    torch.testing.assert_close(pushes.origin, robot.base_pos[:, :2])
    assert pushes.active.all()
    env.step(torch.zeros(3, 20))
    by_hand = -(robot.base_pos[:, :2] - pushes.origin).norm(dim=-1) - (
        robot.base_lin_vel_w[:, :2] * pushes.direction
    ).sum(-1).abs()
    torch.testing.assert_close(g1_rewards.disturbance(env), by_hand)
    assert (by_hand < 0).all()


def test_r_disturb_measures_position_and_velocity_against_the_same_moving_reference():
    """Walking on at the commanded velocity after a push costs nothing; stopping costs in both terms."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=2)
    env.commands[:] = torch.tensor([0.5, 0.0, 0.0])
    push_now(env)
    pushes, robot = env.pushes, env.robot
    pushes.direction[:] = torch.tensor([1.0, 0.0])
    pushes.ref_vel[:] = torch.tensor([0.5, 0.0])  # heading along +x
    pushes.ref_offset[:] = torch.tensor([0.2, 0.0])  # 0.4 s after the push
    robot.base_pos = robot.base_pos.clone()
    robot.base_lin_vel_w = robot.base_lin_vel_w.clone()
    robot.base_pos[:, :2] = pushes.origin + torch.tensor([0.2, 0.0])  # on the reference after 0.4 s
    robot.base_lin_vel_w[0, :2] = torch.tensor([0.5, 0.0])  # env 0 walks on as commanded
    robot.base_lin_vel_w[1, :2] = torch.tensor([0.0, 0.0])  # env 1 stopped
    reward = g1_rewards.disturbance(env)
    assert reward[0].item() == pytest.approx(0.0, abs=1e-6)
    assert reward[1].item() == pytest.approx(-0.5, abs=1e-6)


def test_r_disturb_reference_turns_with_the_commanded_yaw_rate():
    """Told 0.5 m/s forward and 0.5 rad/s left for 1 s from heading pi/2, the reference runs along a circle of
    radius 1 m: worked by hand, it ends (sin 0.5, 1 - cos 0.5) = (0.4794, 0.1224) m ahead and to the left in the
    push-time frame, i.e. (-0.1224, 0.4794) m in the world, moving 0.5 m/s at heading pi/2 + 0.5. A robot on that
    arc pays nothing; one that walked straight on pays for the chord it missed."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=2)
    env.commands[:] = torch.tensor([0.5, 0.0, 0.5])
    push_now(env)
    pushes, robot = env.pushes, env.robot
    pushes.ref_yaw[:] = math.pi / 2
    pushes.ref_vel[:] = torch.tensor([0.0, 0.5])
    steps = round(1.0 / env.dt)
    for _ in range(steps):
        pushes.advance_reference(env.commands)
    end = torch.tensor([-(1 - math.cos(0.5)), math.sin(0.5)])
    torch.testing.assert_close(pushes.ref_offset, end.expand(2, 2), atol=1e-5, rtol=0)
    heading = math.pi / 2 + 0.5
    torch.testing.assert_close(pushes.ref_vel, 0.5 * torch.tensor([math.cos(heading), math.sin(heading)]).expand(2, 2),
                               atol=1e-5, rtol=0)
    pushes.direction[:] = torch.tensor([1.0, 0.0])
    robot.base_pos = robot.base_pos.clone()
    robot.base_lin_vel_w = robot.base_lin_vel_w.clone()
    robot.base_pos[0, :2] = pushes.origin[0] + end  # env 0 turned as told
    robot.base_lin_vel_w[0, :2] = 0.5 * torch.tensor([math.cos(heading), math.sin(heading)])
    robot.base_pos[1, :2] = pushes.origin[1] + torch.tensor([0.0, 0.5])  # env 1 walked straight on, 0.5 m
    robot.base_lin_vel_w[1, :2] = torch.tensor([0.0, 0.5])
    reward = g1_rewards.disturbance(env)
    assert reward[0].item() == pytest.approx(0.0, abs=1e-5)
    missed = math.hypot(0.0 - end[0].item(), 0.5 - end[1].item())
    along_push = abs(0.0 - 0.5 * math.cos(heading))
    assert reward[1].item() == pytest.approx(-missed - along_push, abs=1e-5)


def test_r_disturb_reference_follows_a_sideways_command_in_the_push_time_frame():
    """0.3 m/s to the left with no yaw rate, heading pi/2 at the push: after 0.5 s the reference is 0.15 m along -x."""
    env = make_walk_env(num_envs=1)
    env.commands[:] = torch.tensor([0.0, 0.3, 0.0])
    push_now(env)
    env.pushes.ref_yaw[:] = math.pi / 2
    for _ in range(round(0.5 / env.dt)):
        env.pushes.advance_reference(env.commands)
    torch.testing.assert_close(env.pushes.ref_offset[0], torch.tensor([-0.15, 0.0]), atol=1e-6, rtol=0)


def test_r_disturb_reference_moves_straight_without_reference_turns():
    """The paper's x_last + v_ref t: told 0.5 m/s and 0.5 rad/s from heading 0, after 1 s the reference is 0.5 m
    straight ahead."""
    from pchc_rsl.envs.g1.config import PushConfig

    env = make_walk_env(num_envs=1, push=PushConfig(reference_turns=False))
    env.commands[:] = torch.tensor([0.5, 0.0, 0.5])
    push_now(env)
    env.pushes.ref_yaw[:] = 0.0
    for _ in range(round(1.0 / env.dt)):
        env.pushes.advance_reference(env.commands)
    torch.testing.assert_close(env.pushes.ref_offset[0], torch.tensor([0.5, 0.0]), atol=1e-5, rtol=0)


def test_velocity_average_is_an_exponential_average_of_the_base_velocity_and_yaw_rate():
    """A reference loop over the same steps: v_avg += dt / tau (v - v_avg) from 0 at the reset, v = (base-frame v_x,
    v_y, the yaw's change over the step / dt)."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=2, velocity_average_s=0.1)
    env.commands[:] = torch.tensor([0.5, 0.0, 0.5])
    alpha, expected = env.dt / 0.1, torch.zeros(2, 3)
    yaw = env.robot.yaw.clone()
    generator = torch.Generator().manual_seed(0)
    for _ in range(8):
        env.step(0.5 * torch.randn(2, 20, generator=generator))
        turn = torch.atan2(torch.sin(env.robot.yaw - yaw), torch.cos(env.robot.yaw - yaw))
        yaw = env.robot.yaw.clone()
        velocity = torch.cat([env.robot.base_lin_vel[:, :2], (turn / env.dt).unsqueeze(-1)], dim=-1)
        expected += alpha * (velocity - expected)
    torch.testing.assert_close(env.command.velocity_average, expected, atol=1e-5, rtol=1e-4)
    assert expected.abs().max() > 0.01  # the robot moved
    error = ((env.commands[:, 2] - expected[:, 2]) ** 2) / 0.1**2
    torch.testing.assert_close(g1_rewards.track_average_yaw_rate(env, std=0.1), torch.exp(-error), atol=1e-5, rtol=1e-4)


def test_critic_push_timing_adds_the_window_left_and_the_time_to_the_next_push():
    from pchc_rsl.envs.g1.config import PushConfig

    plain = make_walk_env(num_envs=1, critic_command_state=False)
    env = make_walk_env(num_envs=1, critic_command_state=False, critic_push_timing=True,
                        push=PushConfig(interval_s=(2.0, 2.0), window_s=1.0))
    assert env.get_observations()["critic"].shape[-1] == plain.get_observations()["critic"].shape[-1] + 2
    push_now(env)
    env.step(torch.zeros(1, 20))  # one policy step (0.02 s) after the push
    window_steps, interval_steps = round(1.0 / env.dt), int(2.0 / env.dt)
    expected = [(window_steps - 1) / window_steps, (interval_steps - 1) * env.dt / 2.0]
    torch.testing.assert_close(env.get_observations()["critic"][0, -2:], torch.tensor(expected))


def test_critic_push_size_adds_the_kicks_speed_inside_its_window_and_zero_after():
    from pchc_rsl.envs.g1.config import PushConfig

    plain = make_walk_env(num_envs=2)
    env = make_walk_env(num_envs=2, critic_push_size=True,
                        push=PushConfig(interval_s=(60.0, 60.0), velocity=(0.5, 2.0), window_s=0.1))
    assert env.get_observations()["critic"].shape[-1] == plain.get_observations()["critic"].shape[-1] + 1
    assert (env.get_observations()["critic"][:, -1] == 0).all()
    kick = push_now(env)
    env.step(torch.zeros(2, 20))
    torch.testing.assert_close(env.get_observations()["critic"][:, -1], kick.norm(dim=-1), atol=1e-5, rtol=0)
    for _ in range(round(0.1 / env.dt)):
        env.step(torch.zeros(2, 20))
    assert (env.get_observations()["critic"][:, -1] == 0).all()


def test_amp_root_velocity_is_the_bases_change_over_the_step_in_its_heading_frame():
    """Each amp frame ends with the base's velocity (forward, sideways, yaw rate) over the last step, in its heading
    at the step's end: computed here from the base poses before and after a step (a kick of 1 m/s at 0.5 rad from
    the heading, so both parts are positive); the style reward is built for that width."""
    import math

    from pchc_rsl.algorithms import MultiCriticPPO

    plain = make_walk_env(num_envs=2)
    env = make_walk_env(num_envs=2, amp_root_velocity=True)
    joints = env.num_actions
    assert env.get_observations()["amp"].shape[-1] == plain.get_observations()["amp"].shape[-1] + 5 * 3
    env.step(torch.zeros(2, joints))
    before = env.robot.base_pos[:, :2].clone(), env.robot.yaw.clone()
    env.pushes.request(0, speed=1.0, angle=float(env.robot.yaw[0]) + 0.5)
    env.pushes.request(1, speed=1.0, angle=float(env.robot.yaw[1]) + 0.5)
    obs, *_ = env.step(torch.zeros(2, joints))
    moved, yaw = env.robot.base_pos[:, :2] - before[0], env.robot.yaw
    for i in range(2):
        c, s_ = math.cos(yaw[i]), math.sin(yaw[i])
        turn = math.remainder(float(yaw[i] - before[1][i]), 2 * math.pi)
        expected = torch.tensor([c * moved[i, 0] + s_ * moved[i, 1], -s_ * moved[i, 0] + c * moved[i, 1], turn])
        torch.testing.assert_close(obs["amp"][i, -3:], expected / env.dt, atol=1e-4, rtol=1e-4)
        torch.testing.assert_close(obs["amp"][i, -3 - joints:-3], env.robot.joint_pos[i])
    assert (obs["amp"][:, -3:-1] > 0.3).all()  # the kick: forward and to the left
    resolved = MultiCriticPPO.resolve_amp_config({"motion_files": ["clip.csv"], "joint_names": list(env.cfg.joints)},
                                                 obs, env)
    assert resolved["root_velocity"] is True and resolved["input_dim"] == 5 * (joints + 3)


def test_critic_command_state_adds_the_path_offset_in_the_heading_frame_the_heading_error_and_the_average():
    """A robot facing +y (yaw pi/2) standing 0.3 m along x and 0.1 m along y from its path's point: in its heading
    frame the offset is 0.1 m ahead and 0.3 m to its right, (0.1, -0.3)."""
    import math

    plain = make_walk_env(num_envs=1, critic_command_state=False)
    env = make_walk_env(num_envs=1, critic_command_state=True)
    width = env.get_observations()["critic"].shape[-1]
    assert width == plain.get_observations()["critic"].shape[-1] + 6
    robot = env.robot
    robot.base_pos = robot.base_pos.clone()
    robot.yaw = torch.tensor([math.pi / 2])
    env.command.path.position = robot.base_pos[:, :2] - torch.tensor([[0.3, 0.1]])
    env.command.heading_error[:] = 0.05
    env.command.velocity_average[:] = torch.tensor([0.4, -0.1, 0.2])
    expected = torch.tensor([0.1, -0.3, 0.05, 0.4, -0.1, 0.2])
    torch.testing.assert_close(env.get_observations()["critic"][0, -6:], expected, atol=1e-6, rtol=0)


def test_vertical_r_disturb_adds_the_height_change_since_the_push():
    """A fall (the pelvis 0.5 m lower) with 0.3 m horizontal drift: -sqrt(0.3^2 + 0.5^2) instead of -0.3."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=1)
    env.commands[:] = 0.0
    push_now(env)
    pushes, robot = env.pushes, env.robot
    robot.base_pos = robot.base_pos.clone()
    robot.base_lin_vel_w = torch.zeros_like(robot.base_lin_vel_w)
    robot.base_pos[0] = torch.cat([pushes.origin[0] + torch.tensor([0.3, 0.0]), pushes.origin_height[:1] - 0.5])
    assert g1_rewards.disturbance(env).item() == pytest.approx(-0.3, abs=1e-6)
    assert g1_rewards.disturbance(env, vertical=True).item() == pytest.approx(-(0.3**2 + 0.5**2) ** 0.5, abs=1e-6)


def test_com_r_disturb_charges_the_whole_body_com_instead_of_the_pelvis():
    """The pelvis held on its push origin while the COM drifted 0.2 m: 0 by the pelvis, -0.2 by the COM."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=1)
    env.commands[:] = 0.0
    push_now(env)
    pushes, robot = env.pushes, env.robot
    robot.base_pos, robot.com_pos = robot.base_pos.clone(), robot.com_pos.clone()
    robot.base_lin_vel_w = torch.zeros_like(robot.base_lin_vel_w)
    robot.base_pos[0, :2] = pushes.origin[0]
    robot.com_pos[0, :2] = pushes.com_origin[0] + torch.tensor([0.12, -0.16])
    assert g1_rewards.disturbance(env).item() == pytest.approx(0.0, abs=1e-6)
    assert g1_rewards.disturbance(env, com=True).item() == pytest.approx(-0.2, abs=1e-6)


def test_r_disturb_capture_point_option_charges_the_capture_point_against_the_feet_on_the_ground():
    """COM 0.81 m up moving at (0.9, 0) m/s: omega = sqrt(9.81 / 0.81) = 3.48/s, capture point 0.258 m ahead of the
    COM. Feet at (0.1, 0.1) and (0.5, 0.3): both down, it lies 0.042 m short of their middle in x, 0 in y; only the
    front one down, 0.242 m short of it in x and 0.1 in y; neither down, both count. The pelvis stays on its push
    origin at rest, so r_disturb alone is 0 and the option adds -2 x the distance; outside the window, nothing."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=1)
    env.commands[:] = 0.0
    push_now(env)
    robot = env.robot
    robot.base_pos = robot.base_pos.clone()
    robot.base_pos[0, :2] = env.pushes.origin[0]
    robot.base_lin_vel_w = torch.zeros_like(robot.base_lin_vel_w)
    robot.com_pos = torch.tensor([[0.0, 0.2, 0.81]])
    robot.com_vel = torch.tensor([[0.9, 0.0, 0.0]])
    robot.foot_pos = torch.tensor([[[0.1, 0.1, 0.0], [0.5, 0.3, 0.0]]])
    ahead = 0.9 / math.sqrt(9.81 / 0.81)
    assert g1_rewards.disturbance(env).item() == pytest.approx(0.0, abs=1e-6)
    for contact, support in (([True, True], (0.3, 0.2)), ([False, True], (0.5, 0.3)), ([False, False], (0.3, 0.2))):
        env.feet.contact = torch.tensor([contact])
        distance = math.hypot(ahead - support[0], 0.2 - support[1])
        assert g1_rewards.disturbance(env, capture_point=2.0).item() == pytest.approx(-2 * distance, abs=1e-5)
    env.pushes.window[:] = 0
    assert g1_rewards.disturbance(env, capture_point=2.0).item() == 0.0


def test_com_velocity_sensor_is_the_rate_of_change_of_the_whole_body_com():
    """On a random state of the model: the com_vel sensor against the COM's change of position when the joints and
    the base move by qvel * h (h = 1e-6 s), computed by MuJoCo's kinematics alone; and the env reads that sensor."""
    import mujoco
    import numpy as np

    from pchc_rsl.robots.g1.constants import WALK_JOINTS
    from pchc_rsl.robots.g1.model import build_g1_model

    model = build_g1_model(WALK_JOINTS)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    data.qpos[2] = 0.8
    data.qvel[:] = rng.normal(size=model.nv)
    mujoco.mj_forward(model, data)
    sensor = model.sensor("com_vel")
    reported = data.sensordata[sensor.adr[0]: sensor.adr[0] + 3].copy()
    pelvis, h = model.body("pelvis").id, 1e-6
    before = data.subtree_com[pelvis].copy()
    mujoco.mj_integratePos(model, data.qpos, data.qvel, h)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    np.testing.assert_allclose(reported, (data.subtree_com[pelvis] - before) / h, atol=1e-3)

    env = make_walk_env(num_envs=1)
    env.step(torch.zeros(1, env.num_actions))
    column = env.model.sensor("com_vel").adr[0]
    torch.testing.assert_close(env.robot.com_vel[0], env.physics.substep_sensors[0, -1, column: column + 3].float())


def test_reset_restores_a_valid_standing_state():
    env = make_walk_env(num_envs=2)
    for _ in range(5):
        env.step(torch.randn(2, 20, generator=torch.Generator().manual_seed(0)) * 3)
    env.reset(torch.tensor([1]))
    assert env.episode_length_buf[1] == 0
    assert env.robot.base_pos[1, 2].item() == pytest.approx(0.76)
    torch.testing.assert_close(env.robot.base_quat[1], torch.tensor([1.0, 0.0, 0.0, 0.0]))
    assert (env.robot.joint_pos[1] - env.default_joint_pos).abs().max() <= env.cfg.initial_joint_noise + 1e-6
    assert torch.isfinite(env.get_observations()["policy"]).all()


def test_same_seed_same_trajectory():
    def rollout(seed):
        env = make_walk_env(num_envs=3, seed=seed)
        gen = torch.Generator().manual_seed(7)
        trace = []
        for _ in range(15):
            obs, reward, _, _ = env.step(0.5 * torch.randn(3, 20, generator=gen))
            trace.append(torch.cat([obs["policy"], reward.unsqueeze(-1)], -1))
        return torch.stack(trace)

    a, b, c = rollout(5), rollout(5), rollout(6)
    assert torch.equal(a, b)
    assert not torch.equal(a, c)


def test_two_iteration_training_writes_checkpoint_and_events(tmp_path):
    from pchc_rsl.cli import train

    train.main(["--task", "g1-walk-fast", "--num-envs", "4", "--max-iterations", "2", "--log-dir", str(tmp_path)])
    assert os.path.isfile(tmp_path / "model_1.pt")
    assert glob.glob(str(tmp_path / "events.out.tfevents.*"))
    checkpoint = torch.load(tmp_path / "model_1.pt", weights_only=True)
    assert checkpoint["config"]["task"] == "g1-walk-fast"
    assert math.isclose(checkpoint["config"]["env"]["timestep"], 0.005)


def test_walking_fall_cost_charges_a_terminating_fall():
    """Walking's fall is its termination: a pelvis below termination_height costs fall_cost / dt (x dt = fall_cost)."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=2)
    robot = env.robot
    robot.base_pos = robot.base_pos.clone()
    robot.base_pos[0, 2] = env.cfg.termination_height - 0.1
    reward = g1_rewards.disturbance(env, fall_cost=2.0) - g1_rewards.disturbance(env)
    torch.testing.assert_close(reward * env.dt, torch.tensor([-2.0, 0.0]))
    reward = g1_rewards.stride(env, speed_std=0.25, fall_cost=2.0) - g1_rewards.stride(env, speed_std=0.25)
    torch.testing.assert_close(reward * env.dt, torch.tensor([-2.0, 0.0]))


def test_backward_touchdown_counts_feet_landing_behind_while_walking_is_commanded():
    """Env 0: the left foot lands 5 cm back (1), the right foot 30 cm ahead (0); env 1: both land 2 cm back (2); env 2
    lands back but is told to stand (0); env 3: a backward step held in stance, no touchdown this step (0)."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=4)
    feet = env.feet
    feet.first_contact = torch.tensor([[True, True], [True, True], [True, False], [False, False]])
    feet.step_vector = torch.tensor([[[-0.05, 0.0], [0.3, 0.1]], [[-0.02, 0.0], [-0.02, 0.0]],
                                     [[-0.1, 0.0], [0.0, 0.0]], [[0.0, 0.0], [0.0, 0.0]]])
    feet.stance_step = torch.tensor([[[0.0, 0.0], [0.0, 0.0]]] * 3 + [[[-0.1, 0.0], [0.0, 0.0]]])
    env.commands[:] = torch.tensor([[0.5, 0, 0], [0.5, 0, 0], [0.0, 0, 0], [0.5, 0, 0]])
    torch.testing.assert_close(g1_rewards.backward_touchdown(env), torch.tensor([1.0, 2.0, 0.0, 0.0]))


def test_fall_term_costs_its_weight_once_at_the_fall():
    """The task group's fall: env 0's pelvis is below termination_height, so weight -5 costs 5 of return (x dt)."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=2)
    robot = env.robot
    robot.base_pos = robot.base_pos.clone()
    robot.base_pos[0, 2] = env.cfg.termination_height - 0.1
    torch.testing.assert_close(-5.0 * g1_rewards.fall(env) * env.dt, torch.tensor([-5.0, 0.0]))


def test_gait_metrics_of_a_scripted_walk_and_of_backward_side_taps():
    """Strides of 0.6 m at 0.5 m/s (a 1.2 s cycle, each foot 0.48 s in the air): 0.83 touchdowns per foot per
    second, forward step 0.6 m, no side step or backward touchdown, median air time 0.48 s. Then a foot tapping
    0.1 m behind and 0.2 m beside where it lifted off: every touchdown is backward."""
    from pchc_rsl.envs.g1.contacts import median_from_histogram

    env = make_walk_env(num_envs=1)
    env.metrics.reset(torch.tensor([0]))
    dt, K = env.dt, env.cfg.decimation
    stride, speed, duty = 0.6, 0.5, 0.6
    period = stride / speed
    feet = env.feet
    feet.reset(torch.tensor([0]), torch.full((1, K, 2), 100.0), torch.zeros(1, 2, 3), 0.03)
    steps = int(round(6.0 / dt))
    for i in range(1, steps + 1):
        t = i * dt
        touch, pos = torch.zeros(1, K, 2), torch.zeros(1, 2, 3)
        for foot, offset in enumerate((0.0, 0.5)):
            phase = (t / period + offset) % 1.0
            landed = math.floor(t / period + offset) * stride
            touch[0, :, foot] = 100.0 if phase < duty else 0.0
            pos[0, foot, 0] = landed if phase < duty else landed + stride * (phase - duty) / (1 - duty)
        feet.update(touch, pos, torch.tensor([[1.0, 0.0]]))
        env.metrics.sums.add(env.metrics.step_quantities())
    m = env.episode_metrics(torch.tensor([0]))
    touchdowns = env.metrics.sums.get(torch.tensor([0]))["touchdowns"].item()
    assert touchdowns in (9, 10)  # 5 cycles of each foot in 6 s, the first touchdown of the second foot at 0.6 s
    assert m["cadence"].item() == pytest.approx(touchdowns / (2 * 6.0))
    assert m["forward_step"].item() == pytest.approx(stride, abs=0.02)
    assert m["side_step"].item() == pytest.approx(0.0, abs=1e-6)
    assert m["backward_touchdowns"].item() == 0.0
    assert m["air_time"].item() == pytest.approx((1 - duty) * period, abs=dt + 1e-6)

    env.metrics.reset(torch.tensor([0]))
    feet.reset(torch.tensor([0]), torch.full((1, K, 2), 100.0), torch.zeros(1, 2, 3), 0.03)
    for i in range(40):  # the left foot taps every 4 steps: up 2, down 2, landing back and aside
        up = i % 4 < 2
        touch = torch.full((1, K, 2), 100.0)
        touch[0, :, 0] = 0.0 if up else 100.0
        pos = torch.zeros(1, 2, 3)
        pos[0, 0, :2] = torch.tensor([-0.1, 0.2]) * ((i // 4) + (0 if up else 1))
        feet.update(touch, pos, torch.tensor([[1.0, 0.0]]))
        env.metrics.sums.add(env.metrics.step_quantities())
    m = env.episode_metrics(torch.tensor([0]))
    assert m["backward_touchdowns"].item() == 100.0
    assert m["forward_step"].item() == pytest.approx(-0.1, abs=1e-5)
    assert m["side_step"].item() == pytest.approx(0.2, abs=1e-5)
    assert m["air_time"].item() == pytest.approx(3 * dt)  # 2 steps in the air, the touchdown step counted too
    # the median of the air-time histogram: [1, 1, 2, 5] steps -> 1 step (lower median); no touchdown -> NaN
    counts = torch.zeros(2, 50)
    counts[0, 0], counts[0, 1], counts[0, 4] = 2, 1, 1
    medians = median_from_histogram(counts, 0.02)
    assert medians[0].item() == pytest.approx(0.02) and math.isnan(medians[1].item())


def test_per_foot_gait_heading_and_steering_metrics_of_a_scripted_limping_turn():
    """A hand-worked 6 s episode at dt 0.02: the left foot swings 15 steps and lands 0.4 m ahead, the right swings
    10 steps and lands 0.3 m ahead, each once per 30-step cycle; each foot's first landing (0.1 m, within the first
    0.5 s) is left out. A swing of s steps counts s + 1 steps of air (its touchdown step), so the swings are 0.32 s
    and 0.22 s (ratio 16/11) and the steps 0.4 m and 0.3 m (ratio 4/3). The base turns at 0.5 rad/s from yaw 3.0
    rad (through the +-pi wrap) against a commanded 0.4 rad/s: 0.6 rad = 34.38 degrees off the commanded heading
    and a yaw-rate error of 0.1 rad/s; it moves sideways at 0.25 m/s against 0.3 commanded (error 0.05 m/s), and
    ends 0.8 m to the side of its starting line (facing +y from (1, 2), it ends at (0.2, 7))."""
    env = make_walk_env(num_envs=1)
    ids = torch.tensor([0])
    dt, K = env.dt, env.cfg.decimation
    assert dt == pytest.approx(0.02)
    env.metrics.reset(ids)
    env.feet.reset(ids, torch.full((1, K, 2), 100.0), torch.zeros(1, 2, 3), 0.03)
    env.commands[:] = torch.tensor([0.0, 0.3, 0.4])
    env.robot.base_lin_vel = torch.tensor([[0.0, 0.25, 0.0]])
    env.command.previous_yaw[:] = 3.0
    env.episode_length_buf[:] = 0
    planted = [0.0, 0.0]
    swing_steps, step_length, offset = (15, 10), (0.4, 0.3), (0, 20)
    for i in range(300):
        env.episode_length_buf += 1
        touch, pos = torch.full((1, K, 2), 100.0), torch.zeros(1, 2, 3)
        for foot in range(2):
            phase = (i + offset[foot]) % 30
            if phase < swing_steps[foot]:
                touch[0, :, foot] = 0.0
            elif phase == swing_steps[foot]:
                planted[foot] += 0.1 if planted[foot] == 0.0 else step_length[foot]
            pos[0, foot, 0] = planted[foot]
        env.feet.update(touch, pos, torch.tensor([[1.0, 0.0]]))
        env.robot.yaw = torch.tensor([math.remainder(3.0 + 0.01 * (i + 1), 2 * math.pi)])
        env.command.track(env.robot, torch.zeros(1, dtype=torch.bool))
        env.metrics.sums.add(env.metrics.step_quantities())
    env.metrics.origin[:] = torch.tensor([1.0, 2.0])
    env.metrics.start_heading[:] = torch.tensor([0.0, 1.0])
    env.robot.base_pos = torch.tensor([[0.2, 7.0, 0.75]])
    m = {key: value.item() for key, value in env.episode_metrics(ids).items()}
    assert m["air_time_left"] == pytest.approx(0.32) and m["air_time_right"] == pytest.approx(0.22)
    assert m["swing_ratio"] == pytest.approx(16 / 11)
    assert m["forward_step_left"] == pytest.approx(0.4) and m["forward_step_right"] == pytest.approx(0.3)
    assert m["step_ratio"] == pytest.approx(4 / 3)
    assert m["heading_drift"] == pytest.approx(math.degrees(0.6), abs=1e-3)
    assert m["yaw_rate_error"] == pytest.approx(0.1, abs=1e-5)
    assert m["lateral_speed_error"] == pytest.approx(0.05, abs=1e-6)
    assert m["lateral_drift"] == pytest.approx(0.8, abs=1e-6)


def test_posture_metrics_are_the_episode_means_of_pelvis_height_and_knee_angle():
    """Two envs, 10 steps: env 0 holds the pelvis at 0.76 m with both knees at 0.67 rad; env 1 crouches from 0.76 to
    0.58 m in 0.02 m steps (mean 0.67) with the left knee at 1.2 and the right at 1.6 rad (mean 1.4 rad = 80.21
    deg). The knees are found by name, so a joint reorder cannot hand the metric a hip. Knee torques: env 0 holds
    30 Nm on both knees in every substep, env 1 alternates 40 and -40 Nm on the left and 0 on the right: RMS 30 and
    sqrt(40^2 / 2) = 28.28 Nm (every other joint's torque at 100 Nm counts for nothing)."""
    env = make_walk_env(num_envs=2)
    ids = torch.tensor([0, 1])
    env.metrics.reset(ids)
    left, right = env.cfg.joints.index("left_knee_joint"), env.cfg.joints.index("right_knee_joint")
    for i in range(10):
        joint_pos = torch.zeros(2, len(env.cfg.joints))
        joint_pos[0, [left, right]] = 0.67
        joint_pos[1, left], joint_pos[1, right] = 1.2, 1.6
        env.robot.joint_pos = joint_pos
        env.robot.base_pos = torch.tensor([[0.0, 0.0, 0.76], [0.0, 0.0, 0.76 - 0.02 * i]])
        torques = torch.full((2, env.cfg.decimation, len(env.cfg.joints)), 100.0)
        torques[0, :, [left, right]] = 30.0
        torques[1, :, left] = 40.0 * (-1.0) ** torch.arange(env.cfg.decimation)
        torques[1, :, right] = 0.0
        env.robot.torques_substeps = torques
        env.metrics.sums.add(env.metrics.step_quantities())
    m = env.episode_metrics(ids)
    assert m["base_height"].tolist() == pytest.approx([0.76, 0.67], abs=1e-6)
    assert m["knee_flexion"].tolist() == pytest.approx([math.degrees(0.67), math.degrees(1.4)], abs=1e-4)
    assert m["knee_torque_rms"].tolist() == pytest.approx([30.0, math.sqrt(40.0**2 / 2)], rel=1e-5)


def test_heading_error_is_the_turn_against_the_commanded_turn_since_the_command():
    """Told to turn at 0.5 rad/s, a robot standing still for 20 steps (0.4 s) is 0.2 rad short of its commanded
    heading, plus whatever it turned by itself, read here from the pelvis quaternion; a new command starts over."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=2, command_resample_s=None)
    def yaw():
        w, x, y, z = env.physics.qpos[:, 3:7].double().unbind(-1)
        return torch.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))

    env.reset()
    env.commands[:] = torch.tensor([0.0, 0.0, 0.5])
    start = yaw()
    for _ in range(20):
        env.step(torch.zeros(2, env.num_actions))
    expected = torch.remainder(yaw() - start - 0.5 * 20 * env.dt + math.pi, 2 * math.pi) - math.pi
    torch.testing.assert_close(env.command.heading_error.double(), expected, atol=1e-4, rtol=0)
    assert env.command.heading_error.abs().min() > 0.15
    torch.testing.assert_close(g1_rewards.heading_hold(env, std=0.3), torch.exp(-env.command.heading_error**2 / 0.09))
    env.cfg.command_resample_s = (0.02, 0.02)
    env.command.countdown[:] = 1
    env.command.resample_due(env.robot)
    assert (env.command.heading_error == 0).all()


def test_commands_are_resampled_within_an_episode_with_standing_and_straight_shares():
    """command_resample_s draws a new command every 1-2 s (50-100 steps); over 400 steps of 256 envs each env gets
    4-8 commands, about 20% of them all zero and 25% of the rest with no yaw rate."""
    env = make_walk_env(num_envs=256, command_resample_s=(1.0, 2.0), zero_command_probability=0.2,
                        zero_yaw_rate_probability=0.25, single_axis_probability=0.0)
    seen, draws = [], torch.zeros(256)
    for _ in range(400):
        countdown = env.command.countdown.clone()
        env.command.resample_due(env.robot)
        drew = env.command.countdown > countdown  # a new command restarts the countdown
        draws += drew.float()
        seen.append(env.commands[drew])
    drawn = torch.cat(seen)
    assert 4 <= draws.min() and draws.max() <= 8
    standing = (drawn == 0).all(-1).float().mean().item()
    straight = ((drawn[:, 2] == 0) & (drawn[:, :2] != 0).any(-1)).float().mean().item() / (1 - standing)
    assert standing == pytest.approx(0.2, abs=0.05) and straight == pytest.approx(0.25, abs=0.05)
    r = env.cfg.command_ranges
    for column, key in enumerate(("lin_vel_x", "lin_vel_y", "ang_vel_z")):
        assert r[key][0] <= drawn[:, column].min() and drawn[:, column].max() <= r[key][1]


def test_single_axis_commands_move_one_axis_alone_evenly_over_the_axes():
    """single_axis_probability=0.3 beside a 20% standing share: of 20,000 draws about 80% x 30% = 24% have exactly one
    non-zero axis, a third of them each of v_x, v_y, w_z, spread over its range. Without the option no draw moves one
    axis alone: a uniform draw is never exactly 0, and a zeroed yaw rate leaves v_x and v_y."""
    env = make_walk_env(num_envs=1, zero_command_probability=0.2, zero_yaw_rate_probability=0.25,
                        single_axis_probability=0.3)
    drawn = env.command.draw(20_000)
    moving = drawn != 0
    single = moving.sum(-1) == 1
    assert single.float().mean().item() == pytest.approx(0.8 * 0.3, abs=0.015)
    for column, key in enumerate(("lin_vel_x", "lin_vel_y", "ang_vel_z")):
        alone = drawn[single & moving[:, column], column]
        assert alone.numel() / single.sum().item() == pytest.approx(1 / 3, abs=0.03)
        low, high = env.cfg.command_ranges[key]
        assert low <= alone.min() and alone.max() <= high
        assert alone.std() > (high - low) / 4  # uniform over the range (std (high - low) / sqrt(12)), not a constant
    standing = (~moving).all(-1).float().mean().item()
    assert standing == pytest.approx(0.2, abs=0.015)
    env.cfg.single_axis_probability = 0.0
    assert (env.command.draw(20_000) != 0).sum(-1).eq(1).sum() == 0


def test_single_stance_pays_walking_not_hopping_shuffling_or_standing():
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=4)
    env.feet.contact[:] = torch.tensor([[True, False], [False, False], [True, True], [False, True]])
    env.commands[:] = torch.tensor([[0.5, 0, 0], [0.5, 0, 0], [0.5, 0, 0], [0.0, 0, 0]])
    assert g1_rewards.single_stance(env).tolist() == [1.0, 0.0, 0.0, 0.0]


def test_held_joints_are_springs_at_the_default_pose_with_the_holding_gains():
    """env.held_joints keeps the waist and wrists, unactuated, as a spring-damper with the robot's holding gains: a
    waist turned by 0.1 rad feels -kp * 0.1 (30 Nm) and swings back; the policy's joints and actions are unchanged."""
    import mujoco

    from pchc_rsl.robots.g1.constants import WALK_JOINTS, holding_gains

    held = ["waist_yaw_joint", "left_wrist_roll_joint"]
    env = make_walk_env(num_envs=1, held_joints=held)
    model = env.model
    assert model.nu == env.num_actions == len(WALK_JOINTS)
    waist = model.joint("waist_yaw_joint")
    kp, kd = holding_gains("waist_yaw_joint")
    assert (kp, kd) == (300.0, 3.0)
    assert model.jnt_stiffness[waist.id] == kp and model.dof_damping[waist.dofadr[0]] == kd
    data = mujoco.MjData(model)
    data.qpos[2], data.qpos[3] = 0.76, 1.0
    data.qpos[waist.qposadr[0]] = 0.1
    mujoco.mj_forward(model, data)
    assert data.qfrc_spring[waist.dofadr[0]] == pytest.approx(-kp * 0.1)
    env.step(torch.zeros(1, env.num_actions))
    q = env.physics.qpos[0, waist.qposadr[0]]
    assert abs(float(q)) < 0.05  # held near 0 while the robot stands
    assert env.deploy_metadata()["held_joints"] == {"waist_yaw_joint": [300.0, 3.0], "left_wrist_roll_joint": [20.0, 1.0]}


class HostSyncRecorder:
    """Records the tensor operations of the env's own code that wait on the device on a GPU (item, nonzero, tolist,
    bool/int/float of a tensor, boolean-mask indexing), by wrapping them. On the CPU they cost nothing, so this is
    how a CPU test sees what torch.cuda.set_sync_debug_mode would flag on a GPU."""

    WATCHED = ("item", "nonzero", "tolist", "__bool__", "__int__", "__float__")
    OWN_CODE = (os.sep + "envs" + os.sep, os.sep + "preference.py")
    CPU_ONLY = (os.sep + "batched_mujoco.py",)  # the C MuJoCo backend runs on host memory by construction

    def __init__(self, monkeypatch):
        self.calls = []
        for name in self.WATCHED:
            monkeypatch.setattr(torch.Tensor, name, self._wrap(name, getattr(torch.Tensor, name)))
        for name in ("__getitem__", "__setitem__"):
            monkeypatch.setattr(torch.Tensor, name, self._wrap_index(name, getattr(torch.Tensor, name)))

    def _caller(self):
        import inspect

        frame = inspect.currentframe().f_back.f_back
        where = f"{frame.f_code.co_filename}:{frame.f_lineno}"
        own = any(part in frame.f_code.co_filename for part in self.OWN_CODE)
        return where if own and not any(p in frame.f_code.co_filename for p in self.CPU_ONLY) else None

    def _wrap(self, name, original):
        def wrapped(tensor, *args, **kwargs):
            where = self._caller()
            if where:
                self.calls.append((name, where))
            return original(tensor, *args, **kwargs)
        return wrapped

    def _wrap_index(self, name, original):
        def wrapped(tensor, index, *args):
            parts = index if isinstance(index, tuple) else (index,)
            if any(isinstance(p, torch.Tensor) and p.dtype == torch.bool for p in parts):
                where = self._caller()
                if where:
                    self.calls.append((f"mask {name}", where))
            return original(tensor, index, *args)
        return wrapped


@pytest.mark.parametrize("task", ["g1-walk-fast", "g1-fall-recovery-fast"])
def test_a_step_waits_on_the_device_only_for_the_reset_indices(monkeypatch, task):
    """One host sync per step, the indices of the envs to reset (rsl-rl's own Logger makes the same one
    at every step); pushes, the divergence check, preference resampling, the curriculum and the episode log work
    on masks. The recorder can fail: a boolean-mask assignment in the env is caught (last lines)."""
    from pchc_rsl.training.build import make_env

    cfg = task_config(task)
    cfg.num_envs = 4
    cfg.env.push.interval_s = (0.02, 0.05)  # pushes at almost every step
    cfg.env.preference_resample_prob = 0.5
    cfg.env.episode_length_s = 0.1  # time-outs, so resets happen inside the recorded steps
    env = make_env(cfg)
    actions = torch.zeros(cfg.num_envs, env.num_actions)
    env.step(actions)
    recorder = HostSyncRecorder(monkeypatch)
    for _ in range(8):
        env.step(actions)
    syncs = {where: name for name, where in recorder.calls}
    assert {name for name in syncs.values()} == {"nonzero"}, recorder.calls
    assert len(syncs) == 1 and os.path.join("g1", "env.py") in next(iter(syncs)), recorder.calls
    recorder.calls.clear()
    namespace = {}  # code compiled as if it lived in envs/: the recorder catches its mask assignment
    exec(compile("def clear(w):\n    w[w > 0] = 0\n", os.sep.join(["", "envs", "example.py"]), "exec"), namespace)
    namespace["clear"](env.pushes.window)
    assert [name for name, _ in recorder.calls] == ["mask __setitem__"]


def test_position_error_is_the_base_against_where_the_commands_take_it_since_the_command():
    """Told 0.5 m/s forward, a robot that takes no step for 20 steps (0.4 s) is 0.1-0.2 m behind its commanded
    point (it sways a few cm): the error is its own displacement, read from the physics, minus 0.2 m along its start
    heading. A push's window and a new command start the path over at the robot."""
    from pchc_rsl.envs.g1 import rewards as g1_rewards

    env = make_walk_env(num_envs=2, command_resample_s=None)
    env.reset()
    env.commands[:] = torch.tensor([0.5, 0.0, 0.0])
    start = env.physics.qpos[:, :2].double().clone()
    w, x, y, z = env.physics.qpos[:, 3:7].double().unbind(-1)
    start_yaw = torch.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    for _ in range(20):
        env.step(torch.zeros(2, env.num_actions))
    commanded = 0.5 * 20 * env.dt * torch.stack([start_yaw.cos(), start_yaw.sin()], -1)
    expected = env.physics.qpos[:, :2].double() - start - commanded
    error = env.command.path.error(env.robot.base_pos[:, :2])
    torch.testing.assert_close(error.double(), expected, atol=1e-4, rtol=0)
    assert (error.norm(dim=-1) > 0.1).all()
    by_hand = torch.exp(-(expected.float() ** 2).sum(-1) / 0.2**2)
    torch.testing.assert_close(g1_rewards.position_hold(env, std=0.2), by_hand, atol=1e-4, rtol=0)
    push_now(env)
    env.step(torch.zeros(2, env.num_actions))
    assert env.command.path.error(env.robot.base_pos[:, :2]).abs().max() < 1e-6
    env.pushes.window[:] = 0
    env.step(torch.zeros(2, env.num_actions))
    assert (env.command.path.error(env.robot.base_pos[:, :2]).norm(dim=-1) > 0.005).all()
    env.cfg.command_resample_s = (0.02, 0.02)
    env.command.countdown[:] = 1
    env.command.resample_due(env.robot)
    assert env.command.path.error(env.robot.base_pos[:, :2]).abs().max() < 1e-6
