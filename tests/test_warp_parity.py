"""The parity check compares physics: MuJoCo Warp (its CPU device here) fed the inputs of a C MuJoCo env agrees with
it to float32 precision, and a Warp physics that differs (actuator gains 5% stronger) fails the check."""

import json

import pytest
import torch
from test_g1_env import pytestmark  # noqa: F401  (skip without the G1 model)
from tool_loader import load_tool

pytest.importorskip("mujoco_warp", reason="the warp extra is not installed")


def test_the_same_physics_agrees_and_a_different_one_fails(tmp_path, capsys):
    parity = load_tool("gpu/warp_parity")
    out = tmp_path / "parity.json"
    assert parity.main(["--device", "cpu", "--num-envs", "4", "--steps", "12", "--json", str(out)]) == 0
    same = json.loads(out.read_text())
    assert same["ok"] and same["largest_median"] < 1e-5  # float32 against float64: about 1e-7 rad per step
    assert parity.main(["--device", "cpu", "--num-envs", "4", "--steps", "4", "--perturb-gains", "0.05",
                        "--json", str(out)]) == 1
    differs = json.loads(out.read_text())
    assert not differs["ok"] and differs["largest_median"] > 10 * same["tolerance"]
    assert "ABOVE" in capsys.readouterr().out


def test_mirrored_physics_carries_the_envs_writes_and_resets():
    """A mirror of a C MuJoCo physics gets the env's velocity kick and reset, and so ends where the env's physics
    does (two C MuJoCo physics: the same arithmetic, bit for bit)."""
    from pchc_rsl.envs.physics.batched_mujoco import BatchedMuJoCo
    from pchc_rsl.envs.physics.mirror import MirroredPhysics
    from pchc_rsl.robots.g1.constants import WALK_JOINTS
    from pchc_rsl.robots.g1.model import build_g1_model

    model = build_g1_model(list(WALK_JOINTS), 0.005)
    env_physics, mirror, alone = (BatchedMuJoCo(model, 2, 4) for _ in range(3))
    MirroredPhysics(env_physics, [mirror])
    start = env_physics.qpos.clone()
    start[:, 2] += 0.3
    env_physics.set_qpos_qvel(torch.arange(2), start, torch.zeros(2, model.nv, dtype=torch.float64))
    alone.set_qpos_qvel(torch.arange(2), start, torch.zeros(2, model.nv, dtype=torch.float64))
    ctrl = env_physics.qpos[:, 7:].clone()
    for physics in (env_physics, alone):
        physics.qvel[0, 0] += 1.0  # the env pushes env 0 between two steps
        physics.step(ctrl)
    torch.testing.assert_close(mirror.qpos, env_physics.qpos, rtol=0, atol=0)
    assert (alone.qpos - mirror.qpos).abs().max() == 0 and mirror.qpos[0, 0] > mirror.qpos[1, 0] + 0.01
