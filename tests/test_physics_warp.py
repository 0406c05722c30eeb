"""MuJoCo Warp against C MuJoCo: the same G1 env on both backends (Warp's CPU device) stays together.

Warp's CPU device compiles its kernels on first use (about 30-45 s here, then cached in ~/.cache/warp) and steps
slowly, so the check is small: 4 envs, 20 policy steps, with randomised models, a push and a mid-episode reset.
"""

import math
import re

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
    # with Warp's solver at 10 / 20 iterations (C MuJoCo at 100 / 50), inside the task's buffers
    report = w.physics_report()
    assert w.physics.wp_model.opt.iterations == 10 and w.physics.wp_model.opt.ls_iterations == 20
    assert c.physics.models[0].opt.iterations == 100
    assert 0 < report["max_constraint_rows"] <= w.cfg.warp.constraints_per_env
    assert 0 < report["max_solver_iterations"] <= 10 and 0 <= report["solver_limit_share"] <= 100
    assert report["max_contacts"] > 0
    assert w.physics_report()["max_constraint_rows"] == 0  # the peaks start over at every report


def g1(joints, held=(), timestep=0.005):
    """A G1 model and its standing pose (pelvis 0.76 m, the default joint positions)."""
    from pchc_rsl.robots.g1.model import build_g1_model, default_joint_positions

    model = build_g1_model(list(joints), timestep, held_joints=tuple(held))
    standing = torch.tensor(model.qpos_spring, dtype=torch.float64)
    standing[:7] = torch.tensor([0.0, 0.0, 0.76, 1.0, 0.0, 0.0, 0.0], dtype=torch.float64)
    actuated = model.jnt_qposadr[model.actuator_trnid[:, 0]]
    standing[actuated] = torch.tensor(default_joint_positions(list(joints)), dtype=torch.float64)
    return model, standing


def prone(standing: torch.Tensor) -> torch.Tensor:
    """The same pose lying face down on the floor (pitch +90 deg, pelvis 0.12 m up)."""
    lying = standing.clone()
    lying[2] = 0.12
    lying[3:7] = torch.tensor([math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0], dtype=torch.float64)
    return lying


def test_prone_robots_overflow_64_constraint_rows_and_fit_the_task_buffers():
    """A G1 lying face down needs more than the 64 rows per world Warp was once given: it overflows them, with the
    setting and the size to give; the fall-recovery task's buffers hold it. C MuJoCo, counting the same robot, also
    needs more than 64."""
    import mujoco

    from pchc_rsl.configs import task_config
    from pchc_rsl.envs.physics.warp_mujoco import PhysicsOverflow, WarpMuJoCo
    from pchc_rsl.envs.physics.warp_settings import WarpSettings
    from pchc_rsl.robots.g1.constants import FALL_RECOVERY_HELD_JOINTS, FALL_RECOVERY_JOINTS

    model, standing = g1(FALL_RECOVERY_JOINTS, FALL_RECOVERY_HELD_JOINTS)
    lying = prone(standing)
    hold = lying[model.jnt_qposadr[model.actuator_trnid[:, 0]]]
    data = mujoco.MjData(model)
    data.qpos[:], data.ctrl[:] = lying.numpy(), hold.numpy()
    c_rows = 0
    for _ in range(80):  # 0.4 s: it lands and comes to rest
        mujoco.mj_step(model, data)
        c_rows = max(c_rows, data.nefc)
    assert c_rows > 64

    task = task_config("g1-fall-recovery").env.warp
    for settings, overflows in ((WarpSettings(constraints_per_env=64), True), (task, False)):
        physics = WarpMuJoCo(model, 2, 4, device="cpu", settings=settings)
        qvel = torch.zeros(2, model.nv, dtype=torch.float64)
        physics.set_qpos_qvel(torch.arange(2), standing.repeat(2, 1), qvel)  # the start: a standing robot fits 64
        physics.set_qpos_qvel(torch.arange(2), lying.repeat(2, 1), qvel)
        for _ in range(20):
            physics.step(hold.float().repeat(2, 1))
        if overflows:
            with pytest.raises(PhysicsOverflow, match=r"set env\.warp\.constraints_per_env=1\d\d \(now 64; needed "
                                                       r"(6[5-9]|[7-9]\d) rows in one world\)"):
                physics.overflow_report()
        else:
            report = physics.overflow_report()
            assert 64 < report["max_constraint_rows"] <= task.constraints_per_env


def test_buffers_too_small_for_the_start_are_refused_in_one_line():
    """A standing walker needs about 32 rows (4 contacts per foot, 4 rows each): 8 are refused when the env is
    built, naming the setting and the size needed; a size that is no size, at once."""
    from test_g1_env import make_walk_env

    from pchc_rsl.envs.physics.warp_settings import WarpSettings

    with pytest.raises(ValueError) as refused:
        make_walk_env(num_envs=2, physics="warp", warp=WarpSettings(constraints_per_env=8))
    message = str(refused.value)
    assert "\n" not in message and "env.warp.constraints_per_env=8 is too small" in message
    needed = int(re.search(r"set env\.warp\.constraints_per_env to at least (\d+),", message).group(1))
    assert 16 <= needed <= 64
    with pytest.raises(ValueError, match="env.warp.contacts_per_env must be a whole number >= 1, got 0"):
        make_walk_env(num_envs=2, physics="warp", warp=WarpSettings(contacts_per_env=0))


def test_an_overflowing_constraint_buffer_stops_with_what_to_set():
    """Robots landing need about 30 constraint rows each: a buffer of 4 overflows, and the report names the buffer,
    the setting and a size for it. (They start 0.5 m up, so the start-up check, which refuses 4 for robots on the
    floor, sees none land.)"""
    from pchc_rsl.envs.physics.warp_mujoco import PhysicsOverflow, WarpMuJoCo
    from pchc_rsl.envs.physics.warp_settings import WarpSettings
    from pchc_rsl.robots.g1.constants import WALK_JOINTS

    model, standing = g1(WALK_JOINTS)
    standing[2] += 0.5
    physics = WarpMuJoCo(model, 2, 4, device="cpu", settings=WarpSettings(constraints_per_env=4))
    physics.set_qpos_qvel(torch.arange(2), standing.repeat(2, 1), torch.zeros(2, model.nv, dtype=torch.float64))
    for _ in range(20):  # 0.4 s: they have landed
        physics.step(standing[7:].float().repeat(2, 1))
    with pytest.raises(PhysicsOverflow, match=r"constraint rows \(njmax\) \[NEFC\]; set "
                                               r"env\.warp\.constraints_per_env=\d+ \(now 4; needed \d+ rows"):
        physics.overflow_report()


def test_torch_views_and_streams_are_made_once(monkeypatch):
    """After construction, steps, resets and sanitising never call wp.to_torch (each call builds a new tensor)."""
    import warp as wp

    from pchc_rsl.envs.physics.warp_mujoco import WarpMuJoCo
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

    from pchc_rsl.envs.g1.config import RandomizationConfig
    from pchc_rsl.envs.g1.randomization import model_variants
    from pchc_rsl.envs.physics.warp_mujoco import WarpMuJoCo, differing_fields
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
    from pchc_rsl.envs.physics.batched_mujoco import BatchedMuJoCo
    from pchc_rsl.envs.physics.warp_mujoco import WarpMuJoCo
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

    from pchc_rsl.envs.physics import warp_mujoco
    from pchc_rsl.robots.g1.constants import WALK_JOINTS
    from pchc_rsl.robots.g1.model import build_g1_model

    physics = warp_mujoco.WarpMuJoCo(build_g1_model(list(WALK_JOINTS), 0.005), 2, 4, device="cpu")
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
    monkeypatch.setattr(warp_mujoco.mjw, "forward", lambda model, data: calls.append(("forward",)))
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


def test_solver_limit_hits_are_counted_on_the_device_and_never_printed(capfd):
    """One solver iteration cannot converge with feet on the floor: each world-step then ends at the limit. mujoco_warp
    would print a line per world and step; here nothing is printed and the share of hits is reported."""
    from pchc_rsl.envs.physics.warp_mujoco import WarpMuJoCo
    from pchc_rsl.envs.physics.warp_settings import WarpSettings
    from pchc_rsl.robots.g1.constants import WALK_JOINTS

    model, standing = g1(WALK_JOINTS)
    physics = WarpMuJoCo(model, 2, 4, device="cpu", settings=WarpSettings(solver_iterations=1))
    physics.set_qpos_qvel(torch.arange(2), standing.repeat(2, 1), torch.zeros(2, model.nv, dtype=torch.float64))
    physics.overflow_report()
    for _ in range(5):
        physics.step(standing[7:].float().repeat(2, 1))
    report = physics.overflow_report()
    out, err = capfd.readouterr()
    assert "limit reached" not in out + err
    assert report["solver_iterations_limit"] == 1 and report["max_solver_iterations"] == 1
    assert report["solver_limit_share"] > 20  # the feet land in the first steps; from then on, every step
    assert physics.overflow_report()["solver_limit_share"] == 0  # counted since the last report only
