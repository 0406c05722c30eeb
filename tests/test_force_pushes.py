"""Force pushes: a force on one body over a set time, as a hand or a door pushes a robot (envs/g1/pushes.py)."""

import math
from types import SimpleNamespace

import mujoco
import pytest
import torch

from pchc_rsl.envs.g1.config import ForcePushConfig, PushConfig
from pchc_rsl.envs.g1.pushes import Pushes, check_push_config

FREE_BOX = """
<mujoco>
  <option timestep="0.005" gravity="0 0 0"/>
  <worldbody>
    <body name="box" pos="0 0 1"><freejoint name="free"/><geom type="box" size="0.1 0.1 0.1" mass="2.5"/></body>
  </worldbody>
  <actuator><motor joint="free" gear="1 0 0 0 0 0"/></actuator>
</mujoco>
"""


def push_a_free_box(physics, magnitude: float, duration_s: float, steps: int = 6):
    """A free 2.5 kg box in zero gravity, pushed once by a force of ``magnitude`` N for ``duration_s`` through the
    Pushes of an env with 0.02 s steps; returns its linear velocity after ``steps`` steps and the push direction
    (``last_pushes`` keeps the Pushes)."""
    model = physics.model
    cfg = PushConfig(interval_s=(10.0, 10.0), velocity_share=0.0,
                     force=ForcePushConfig(share=1.0, bodies={"box": 1.0}, magnitude=(magnitude, magnitude),
                                           duration_s=(duration_s, duration_s)))
    check_push_config(cfg, [model.body(i).name for i in range(model.nbody)])
    pushes = Pushes(cfg, 1, 0.02, torch.Generator(physics.device).manual_seed(0),
                    body_ids={"box": model.body("box").id}, robot_mass=2.5)
    pushes.reset(torch.tensor([0]))
    pushes.countdown[:] = 2  # one step without a push, then the push
    for _ in range(steps):
        qpos = physics.qpos.float()
        robot = SimpleNamespace(base_pos=qpos[:, :3], base_quat=qpos[:, 3:7], com_pos=qpos[:, :3])
        pushes.apply(physics, robot, torch.zeros(1, 3))
        physics.body_forces.zero_()
        pushes.add_forces(physics)
        physics.step(torch.zeros(1, model.nu))
        pushes.advance_window()
    push_a_free_box.last_pushes = pushes
    return physics.qvel[0, :3].double(), pushes.direction[0].double()


def push_every_env_once(pushes: Pushes, num_bodies: int) -> SimpleNamespace:
    """Start a push in every env of ``pushes`` on a stand-in physics (free-joint velocities and body forces of
    ``num_bodies`` bodies) with the robots at the origin, unturned; returns that physics."""
    n = len(pushes.countdown)
    physics = SimpleNamespace(qvel=torch.zeros(n, 6, dtype=torch.float64),
                              body_forces=torch.zeros(n, num_bodies, 6, dtype=torch.float64))
    robot = SimpleNamespace(base_pos=torch.zeros(n, 3), base_quat=torch.tensor([[1.0, 0, 0, 0]]).expand(n, 4),
                            com_pos=torch.zeros(n, 3))
    pushes.countdown[:] = 1
    pushes.apply(physics, robot, torch.zeros(n, 3))
    return physics


def free_box_physics(backend: str):
    model = mujoco.MjModel.from_xml_string(FREE_BOX)
    if backend == "warp":
        pytest.importorskip("mujoco_warp", reason="the warp extra is not installed")
        from pchc_rsl.envs.physics.warp_mujoco import WarpMuJoCo

        return WarpMuJoCo(model, 1, 4, device="cpu", with_body_forces=True)
    from pchc_rsl.envs.physics.batched_mujoco import BatchedMuJoCo

    return BatchedMuJoCo(model, 1, 4, with_body_forces=True)


@pytest.mark.parametrize("duration_s", [0.08, 0.05])
def test_a_force_on_a_free_body_changes_its_momentum_by_force_times_duration(duration_s):
    """400 N for 0.08 s (4 whole steps) or 0.05 s (2.5 steps: the third gets half the force) on 2.5 kg: the box
    ends at 400 x duration / 2.5 m/s along the push's horizontal direction, and stays there once the push ends."""
    velocity, direction = push_a_free_box(free_box_physics("mujoco"), 400.0, duration_s)
    expected = 400.0 * duration_s / 2.5
    torch.testing.assert_close(velocity[:2], expected * direction, atol=1e-6, rtol=1e-6)  # float32 forces
    assert abs(velocity[2]) < 1e-12 and abs(direction.norm() - 1) < 1e-6


def test_a_push_size_is_the_speed_it_gives_the_whole_body():
    """The size the critic can see (``Pushes.size``): a force's impulse over the body's mass is the speed the free
    box ends with; a kick's size is the kick's speed, read off the velocity it added."""
    velocity, _ = push_a_free_box(free_box_physics("mujoco"), 400.0, 0.05)
    assert push_a_free_box.last_pushes.size[0].item() == pytest.approx(velocity[:2].norm().item(), rel=1e-5)

    n = 64
    cfg = PushConfig(interval_s=(10.0, 10.0), velocity=(0.5, 2.0), velocity_share=1.0,
                     force=ForcePushConfig(share=1.0, bodies={"box": 1.0}, magnitude=(100.0, 500.0),
                                           duration_s=(0.05, 0.1)))
    pushes = Pushes(cfg, n, 0.02, torch.Generator().manual_seed(3), body_ids={"box": 1}, robot_mass=2.5)
    physics = push_every_env_once(pushes, num_bodies=2)
    forced = pushes.force_left_s > 0
    assert 0 < forced.sum() < n
    kick_speed = physics.qvel[:, :2].norm(dim=-1).float()
    torch.testing.assert_close(pushes.size[~forced], kick_speed[~forced], atol=1e-6, rtol=0)
    impulse_speed = pushes.force[:, :2].norm(dim=-1) * pushes.force_left_s / 2.5
    torch.testing.assert_close(pushes.size[forced], impulse_speed[forced], atol=1e-5, rtol=1e-5)


def test_the_warp_path_gives_the_same_push_as_c_mujoco():
    c_velocity, c_direction = push_a_free_box(free_box_physics("mujoco"), 400.0, 0.05)
    w_velocity, w_direction = push_a_free_box(free_box_physics("warp"), 400.0, 0.05)
    torch.testing.assert_close(w_direction, c_direction, atol=1e-6, rtol=0)
    torch.testing.assert_close(w_velocity, c_velocity, atol=1e-5, rtol=1e-5)


def test_push_settings_that_cannot_work_are_refused_in_one_line_naming_the_setting():
    bodies = ["world", "pelvis", "torso_link"]
    bad = [(PushConfig(force=ForcePushConfig(share=1.0, bodies={"head": 1.0})), "env.push.force.bodies"),
           (PushConfig(force=ForcePushConfig(magnitude=(-10.0, 300.0))), "env.push.force.magnitude"),
           (PushConfig(force=ForcePushConfig(duration_s=(0.1, 0.05))), "env.push.force.duration_s"),
           (PushConfig(velocity_share=0.0), "env.push.velocity_share"),
           (PushConfig(velocity_share=-1.0, force=ForcePushConfig(share=2.0)), "env.push.velocity_share"),
           (PushConfig(force=ForcePushConfig(vertical=(0.0, 1.5))), "env.push.force.vertical"),
           (PushConfig(force=ForcePushConfig(share=1.0, bodies={"pelvis": 0.0})), "env.push.force.bodies")]
    for cfg, setting in bad:
        with pytest.raises(ValueError, match=setting.replace(".", r"\.")) as error:
            check_push_config(cfg, bodies)
        assert "\n" not in str(error.value)
    check_push_config(PushConfig(force=ForcePushConfig(share=1.0, bodies={"pelvis": 1.0})), bodies)


def angular_momentum_and_lever(env, torso: int):
    """The whole robot's angular momentum about its centre of mass (world frame) and the torso's centre of mass
    relative to the robot's, read from the C physics state of env 0."""
    from pchc_rsl.envs.physics.batched_mujoco import STATE_SPEC

    model = env.physics.models[0]
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, env.physics.state[0], STATE_SPEC)
    mujoco.mj_forward(model, data)
    mujoco.mj_subtreeVel(model, data)
    pelvis = model.body("pelvis").id
    lever = data.xipos[torso] - data.subtree_com[pelvis]
    return torch.tensor(data.subtree_angmom[pelvis].copy()), torch.tensor(lever)


@pytest.mark.parametrize("kind", ["force", "kick"])
def test_a_force_on_the_torso_turns_the_robot_a_velocity_kick_does_not(kind):
    """In flight (no contact), a force F for time T on the torso changes the robot's angular momentum about its
    centre of mass by r x F T, r the torso's lever from that centre: the push turns the robot. The velocity kick of
    the same whole-body speed moves every body alike and turns it not at all."""
    from test_g1_env import g1_available, make_walk_env

    if not g1_available():
        pytest.skip("G1 model unavailable (set MENAGERIE_ROOT)")
    env = make_walk_env(num_envs=1, push=PushConfig(interval_s=(60.0, 60.0), force=ForcePushConfig(share=1.0)),
                        randomization=SimpleNamespace(enabled=False), action_delay_s=(0.0, 0.0))
    qpos, qvel = env.initial_state(torch.tensor([0]))
    qpos[:, 2] = 1.5  # in the air: no contact during the push
    env.physics.set_qpos_qvel(torch.tensor([0]), qpos, qvel)
    env.robot.read()
    torso = env.model.body("torso_link").id
    before, lever = angular_momentum_and_lever(env, torso)
    mass = float(env.model.body_subtreemass[env.model.body("pelvis").id])
    force, duration = 400.0, 0.08
    if kind == "force":
        env.pushes.request(0, angle=0.0, force=force, duration_s=duration, body_id=torso)
    else:
        env.pushes.request(0, speed=force * duration / mass, angle=0.0)
    for _ in range(4):
        env.step(torch.zeros(1, env.num_actions))
    after, _ = angular_momentum_and_lever(env, torso)
    change = after - before
    if kind == "force":
        expected = torch.linalg.cross(lever, torch.tensor([force * duration, 0.0, 0.0], dtype=torch.float64))
        assert expected.norm() > 5.0  # N m s: the torso's centre of mass sits well above the robot's
        torch.testing.assert_close(change, expected, atol=0.1 * expected.norm().item(), rtol=0)
    else:
        assert change.norm() < 0.05


def test_a_push_config_mixes_kicks_and_forces_by_their_shares_and_bodies_by_their_weights():
    """velocity_share 3 against force.share 1: a quarter of 8000 pushes are forces, spread 1:3 over pelvis (id 1)
    and torso (id 2); the others kick; each push opens its window at its onset."""
    n = 8000
    cfg = PushConfig(interval_s=(10.0, 10.0), velocity=(1.0, 1.0), velocity_share=3.0,
                     force=ForcePushConfig(share=1.0, bodies={"pelvis": 1.0, "torso_link": 3.0}))
    pushes = Pushes(cfg, n, 0.02, torch.Generator().manual_seed(1), body_ids={"pelvis": 1, "torso_link": 2})
    physics = push_every_env_once(pushes, num_bodies=3)
    forced = pushes.force_left_s > 0
    kicked = physics.qvel[:, :2].norm(dim=-1) > 0.5
    assert not (forced & kicked).any() and (forced | kicked).all() and pushes.active.all()
    assert forced.float().mean().item() == pytest.approx(0.25, abs=0.02)
    on_torso = (pushes.force_body[forced] == 2).float().mean().item()
    assert on_torso == pytest.approx(0.75, abs=0.03)
    magnitude = pushes.force[forced].norm(dim=-1)
    assert magnitude.min() >= 300.0 and magnitude.max() <= 600.0 and pushes.force[forced][:, 2].abs().max() == 0.0
    pushes.add_forces(physics)
    torch.testing.assert_close(physics.body_forces[:, :, :3].sum(1), pushes.force.double() * forced.unsqueeze(-1))


def test_the_push_response_header_says_whether_it_kicks_or_pushes_with_forces():
    from tool_loader import load_tool

    words = load_tool("diagnostics/push_response").pushes_in_words
    forces = ForcePushConfig(share=1.0, bodies={"torso_link": 1.0, "pelvis": 1.0}, magnitude=(300.0, 600.0),
                             duration_s=(0.1, 0.1))
    assert words(PushConfig(velocity=(2.25, 2.25))) == "kicks of 2.25-2.25 m/s"
    assert words(PushConfig(velocity_share=0.0, force=forces)) == \
        "forces of 300-600 N for 0.1-0.1 s on torso_link, pelvis"
    assert words(PushConfig(velocity=(0.5, 2.0), force=forces)).startswith("kicks of 0.5-2 m/s and forces of 300-600 N")
