"""MuJoCo Warp against C MuJoCo: the same G1 env on both backends (Warp's CPU device) stays together.

Warp's CPU device compiles its kernels on first use (about 30-45 s here, then cached in ~/.cache/warp) and steps
slowly, so the check is small: 4 envs, 20 policy steps, with randomised models, a push and a mid-episode reset.
"""

import pytest
import torch
from test_g1_env import make_walk_env, pytestmark  # noqa: F401  (skip without the G1 model)

pytest.importorskip("mujoco_warp", reason="the warp extra is not installed")


def test_warp_backend_follows_c_mujoco_through_pushes_resets_and_randomisation():
    envs = {backend: make_walk_env(num_envs=4, seed=3, physics=backend) for backend in ("mujoco", "warp")}
    c, w = envs["mujoco"], envs["warp"]
    assert w.physics.device == "cpu" and w.physics.qpos.dtype == torch.float32  # Warp's own arrays, viewed
    friction = w.physics.wp_model.geom_friction
    assert friction.shape[0] == 4  # one per model variant (4 envs, 4 variants)

    actions = torch.Generator().manual_seed(0)
    for step in range(20):
        if step == 3:  # push every env now
            for env in envs.values():
                env.pushes.countdown[:] = 1
        if step == 10:  # a mid-episode reset of env 1
            for env in envs.values():
                env.reset(torch.tensor([1]))
            # what the env reads right after a reset describes the new state on both backends
            torch.testing.assert_close(w.robot.foot_pos, c.robot.foot_pos, atol=1e-3, rtol=0)
            torch.testing.assert_close(w.robot.com_pos, c.robot.com_pos, atol=1e-3, rtol=0)
        a = 0.3 * (2 * torch.rand(4, c.num_actions, generator=actions) - 1)
        (_, reward_c, _, extras_c), (_, reward_w, _, extras_w) = c.step(a), w.step(a)
        joint_error = (c.robot.joint_pos - w.robot.joint_pos).abs().max().item()
        assert joint_error < 1e-3, f"step {step}: joint positions differ by {joint_error:.2e} rad"
        torch.testing.assert_close(w.robot.foot_pos, c.robot.foot_pos, atol=1e-3, rtol=0)
        torch.testing.assert_close(w.robot.com_pos, c.robot.com_pos, atol=1e-3, rtol=0)
        assert torch.equal(w.feet.contact, c.feet.contact)
        torch.testing.assert_close(w.pushes.max_deviation, c.pushes.max_deviation, atol=1e-3, rtol=0)
        torch.testing.assert_close(extras_w["reward_groups"], extras_c["reward_groups"], atol=2e-3, rtol=1e-3)
        torch.testing.assert_close(reward_w, reward_c, atol=2e-3, rtol=1e-3)
    assert (c.pushes.max_deviation[[0, 2, 3]] > 0).all()  # the pushes happened
    assert c.episode_length_buf[1] == 10 and w.episode_length_buf[1] == 10  # and the reset
