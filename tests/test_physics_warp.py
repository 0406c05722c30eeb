"""MuJoCo Warp against C MuJoCo: the same G1 env on both backends (Warp's CPU device) stays together.

Warp's CPU device compiles its kernels on first use (about 30-45 s here, then cached in ~/.cache/warp) and steps
slowly, so the check is small: 4 envs, 20 policy steps, with randomised models, a push and a mid-episode reset.
"""

import pytest
import torch
from test_g1_env import make_walk_env, pytestmark  # noqa: F401  (skip without the G1 model)

pytest.importorskip("mujoco_warp", reason="the warp extra is not installed")


def test_warp_backend_follows_c_mujoco_through_pushes_resets_and_randomisation():
    envs = {backend: make_walk_env(num_envs=4, seed=3, physics=backend, action_delay_s=(0.0, 0.0))
            for backend in ("mujoco", "warp")}
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
    # with Warp's solver at 10 / 20 iterations (C MuJoCo at 100 / 50), inside the buffers sized for the G1
    from pchc_rsl.envs.physics_warp import CONSTRAINTS_PER_ENV

    report = w.physics_report()
    assert w.physics.wp_model.opt.iterations == 10 and w.physics.wp_model.opt.ls_iterations == 20
    assert c.physics.models[0].opt.iterations == 100
    assert 0 < report["max_constraint_rows"] <= CONSTRAINTS_PER_ENV and 0 < report["max_solver_iterations"] <= 10
    assert report["max_contacts"] > 0
    assert w.physics_report()["max_constraint_rows"] == 0  # the peaks start over at every report


def test_an_overflowing_constraint_buffer_stops_with_what_to_raise():
    """Standing robots need about 30 constraint rows each; 4 overflow, and the report says which buffer."""
    from pchc_rsl.envs.physics_warp import PhysicsOverflow, WarpMuJoCo
    from pchc_rsl.robots.g1.constants import WALK_JOINTS
    from pchc_rsl.robots.g1.model import build_g1_model, default_joint_positions

    model = build_g1_model(list(WALK_JOINTS), 0.005)
    physics = WarpMuJoCo(model, 2, 2, device="cpu", constraints_per_env=4)
    qpos = torch.zeros(2, model.nq, dtype=torch.float64)
    qpos[:, 2], qpos[:, 3] = 0.76, 1.0
    qpos[:, 7:] = torch.tensor(default_joint_positions(list(WALK_JOINTS)), dtype=torch.float64)
    physics.set_qpos_qvel(torch.arange(2), qpos, torch.zeros(2, model.nv, dtype=torch.float64))
    for _ in range(10):  # 0.1 s: the feet, a few mm above the floor at the start, have landed
        physics.step(qpos[:, 7:].float())
    with pytest.raises(PhysicsOverflow, match="NEFC .*constraints_per_env"):
        physics.overflow_report()


def test_torch_views_and_streams_are_made_once(monkeypatch):
    """After construction, steps, resets and sanitising never call wp.to_torch (each call builds a new tensor)."""
    import warp as wp

    from pchc_rsl.envs.physics_warp import WarpMuJoCo
    from pchc_rsl.robots.g1.constants import WALK_JOINTS
    from pchc_rsl.robots.g1.model import build_g1_model

    physics = WarpMuJoCo(build_g1_model(list(WALK_JOINTS), 0.005), 2, 2, device="cpu")
    calls = []
    to_torch = wp.to_torch
    monkeypatch.setattr(wp, "to_torch", lambda *a, **k: (calls.append(1), to_torch(*a, **k))[1])
    qpos, qvel = physics.qpos.double().clone(), physics.qvel.double().clone()
    physics.step(torch.zeros(2, physics.model.nu))
    physics.set_qpos_qvel(torch.tensor([1]), qpos[1:], qvel[1:])
    physics.sanitize(torch.tensor([True, False]))
    physics.overflow_report()
    assert calls == []


def test_every_field_in_which_the_variants_differ_is_batched_per_world():
    """Randomised variants differ in friction, pelvis mass and gains, and mj_setConst derives more from them
    (subtree masses, body_invweight0, dof_invweight0, actuator_acc0): each such field is batched, and the Warp
    model's rows equal the C variants' values field by field."""
    import numpy as np

    from pchc_rsl.envs.g1_config import RandomizationConfig
    from pchc_rsl.envs.g1_randomization import model_variants
    from pchc_rsl.envs.physics_warp import WarpMuJoCo, differing_fields
    from pchc_rsl.robots.g1.constants import WALK_JOINTS
    from pchc_rsl.robots.g1.model import build_g1_model

    model = build_g1_model(list(WALK_JOINTS), 0.005)
    models = model_variants(model, RandomizationConfig(num_model_variants=3), 6, np.random.default_rng(1))
    variants = models[:3]
    expected = {name for name in dir(model) if not name.startswith("_")
                and isinstance(getattr(model, name), np.ndarray)
                and any(not np.array_equal(getattr(v, name), getattr(model, name)) for v in variants)}
    assert {"body_invweight0", "dof_invweight0", "body_subtreemass", "geom_friction"} <= expected
    physics = WarpMuJoCo(models, 6, 4, device="cpu")
    assert set(physics.batched_fields) == set(differing_fields(variants))
    import warp as wp

    for name in physics.batched_fields:
        batched = wp.to_torch(getattr(physics.wp_model, name)).numpy()
        for index, variant in enumerate(variants):
            np.testing.assert_allclose(batched[index].reshape(-1), getattr(variant, name).reshape(-1), rtol=1e-5,
                                       atol=1e-6, err_msg=name)
    assert {"body_invweight0", "dof_invweight0"} <= set(physics.batched_fields)


def test_a_control_per_substep_reaches_the_physics_on_both_backends():
    """An action delay hands the physics one control per substep: the old target for the first substeps, the new
    one after. Both backends follow the same switch (and it matters: holding the new target all step differs)."""
    from pchc_rsl.envs.physics import BatchedMuJoCo
    from pchc_rsl.envs.physics_warp import WarpMuJoCo
    from pchc_rsl.robots.g1.constants import WALK_JOINTS
    from pchc_rsl.robots.g1.model import build_g1_model, default_joint_positions

    model = build_g1_model(list(WALK_JOINTS), 0.005)
    default = torch.tensor(default_joint_positions(list(WALK_JOINTS)), dtype=torch.float64)
    qpos = torch.zeros(2, model.nq, dtype=torch.float64)
    qpos[:, 2], qpos[:, 3] = 0.8, 1.0  # in the air: no contact, so float32 and float64 stay together
    qpos[:, 7:] = default
    switched = default.repeat(2, 4, 1)
    switched[:, 2:, WALK_JOINTS.index("left_knee_joint")] += 0.5
    results = {}
    for name, physics in (("c", BatchedMuJoCo(model, 2, 4)), ("warp", WarpMuJoCo(model, 2, 4, device="cpu"))):
        physics.set_qpos_qvel(torch.arange(2), qpos, torch.zeros(2, model.nv, dtype=torch.float64))
        physics.step(switched.to(physics.qpos.dtype))
        results[name] = physics.qpos.double().clone()
    torch.testing.assert_close(results["warp"], results["c"], atol=1e-4, rtol=0)
    held = BatchedMuJoCo(model, 2, 4)
    held.set_qpos_qvel(torch.arange(2), qpos, torch.zeros(2, model.nv, dtype=torch.float64))
    held.step(switched[:, -1])
    assert (held.qpos - results["c"]).abs().max() > 1e-3


def test_cuda_graph_is_captured_and_replayed_on_its_own_stream_ordered_with_torchs(monkeypatch):
    """No GPU needed: a CPU Warp physics pretends its device is CUDA, and Warp's stream, capture and launch calls
    are recorders. The first step captures on the stream made for it (never torch's, the legacy default stream
    CUDA refuses), later steps replay there, and each step waits for torch's stream and makes torch wait for it."""
    import contextlib

    import warp as wp

    from pchc_rsl.envs import physics_warp
    from pchc_rsl.robots.g1.constants import WALK_JOINTS
    from pchc_rsl.robots.g1.model import build_g1_model

    physics = physics_warp.WarpMuJoCo(build_g1_model(list(WALK_JOINTS), 0.005), 2, 4, device="cpu")
    calls = []

    class Stream:
        def __init__(self, name):
            self.name = name

        def wait_stream(self, other):
            calls.append(("wait", self.name, other.name))

    work, torch_stream = Stream("own"), Stream("torch")

    class Capture:
        def __init__(self, device=None, stream=None):
            calls.append(("capture", stream.name))
            self.graph = "graph"

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

    class Device:
        is_cuda = True

    physics.wp_device, physics._capture_stream = Device(), work
    monkeypatch.setattr(physics, "_stream", lambda: torch_stream)
    monkeypatch.setattr(physics, "_substeps", lambda: calls.append(("substeps",)))
    monkeypatch.setattr(wp, "ScopedDevice", lambda device: contextlib.nullcontext())
    monkeypatch.setattr(wp, "ScopedStream", lambda stream, sync_enter=True: (
        calls.append(("on", stream.name)), contextlib.nullcontext())[1])
    monkeypatch.setattr(wp, "ScopedCapture", Capture)
    monkeypatch.setattr(wp, "capture_launch", lambda graph, stream=None: calls.append(("launch", graph, stream.name)))
    ctrl = torch.zeros(2, physics.model.nu)
    physics.step(ctrl)
    assert calls == [("wait", "own", "torch"), ("on", "own"), ("substeps",), ("capture", "own"), ("substeps",),
                     ("wait", "torch", "own")]
    calls.clear()
    physics.step(ctrl)
    assert calls == [("wait", "own", "torch"), ("on", "own"), ("launch", "graph", "own"), ("wait", "torch", "own")]
    # a reset's forward pass: its own graph, captured at the first reset, replayed at the next (not the step's)
    monkeypatch.setattr(physics_warp.mjw, "forward", lambda model, data: calls.append(("forward",)))
    monkeypatch.setattr(Capture, "__init__", lambda self, device=None, stream=None: (
        calls.append(("capture", stream.name)), setattr(self, "graph", "forward graph"))[0])
    qpos, qvel = physics.qpos[:1].double().clone(), physics.qvel[:1].double().clone()
    calls.clear()
    physics.set_qpos_qvel(torch.tensor([0]), qpos, qvel)
    assert calls == [("wait", "own", "torch"), ("on", "own"), ("forward",), ("capture", "own"), ("forward",),
                     ("wait", "torch", "own")]
    calls.clear()
    physics.set_qpos_qvel(torch.tensor([1]), qpos, qvel)
    physics.step(ctrl)
    assert calls == [("wait", "own", "torch"), ("on", "own"), ("launch", "forward graph", "own"), ("wait", "torch", "own"),
                     ("wait", "own", "torch"), ("on", "own"), ("launch", "graph", "own"), ("wait", "torch", "own")]
