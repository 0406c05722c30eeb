import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from pchc_rsl.amp import G1_CSV_JOINTS, AMPDiscriminator, MotionWindows, ReplayBuffer, load_motion, load_motions


@pytest.fixture(autouse=True)
def one_torch_thread():
    """These networks are tiny: intra-op threads only contend with other CPU work (tens of times slower on 2 cores)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def write_csv(path: Path, data: np.ndarray) -> Path:
    np.savetxt(path, data, delimiter=",", fmt="%.9f")
    return path


def write_npz(path: Path, **arrays) -> Path:
    np.savez(path, **arrays)
    return path


def random_csv(tmp_path: Path, frames: int = 31, name: str = "clip.csv", seed: int = 0) -> tuple[Path, np.ndarray]:
    data = np.random.default_rng(seed).uniform(-1.0, 1.0, size=(frames, 36))
    return write_csv(tmp_path / name, data), data


# ----------------------------------------------------------------------------------------------------------- loader


def test_g1_csv_joint_order():
    assert len(G1_CSV_JOINTS) == 29
    assert G1_CSV_JOINTS[0] == "left_hip_pitch_joint"
    assert G1_CSV_JOINTS[9] == "right_knee_joint"
    assert G1_CSV_JOINTS[12:15] == ("waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint")
    assert G1_CSV_JOINTS[-1] == "right_wrist_yaw_joint"


def test_csv_selects_joints_by_name_in_the_requested_order(tmp_path):
    path, data = random_csv(tmp_path)
    # columns: 3 root position + 4 root quaternion, then joints; right_knee is joint 9, left_hip_pitch joint 0,
    # right_wrist_yaw joint 28
    out = load_motion(path, ["right_knee_joint", "left_hip_pitch_joint", "right_wrist_yaw_joint"], fps_out=30)
    assert out.dtype == torch.float32 and out.shape == (31, 3)
    np.testing.assert_allclose(out.numpy(), data[:, [16, 7, 35]], atol=1e-6)


@pytest.mark.parametrize("frames, expected_frames", [(31, 51), (30, 49)])
def test_csv_resampling_30_to_50_fps_matches_numpy_interp(tmp_path, frames, expected_frames):
    # 31 frames span exactly 1 s -> 51 frames at 50 fps; 30 frames span 29/30 s -> frames at 0, 0.02, ..., 0.96 s
    path, data = random_csv(tmp_path, frames)
    out = load_motion(path, ["left_knee_joint", "waist_pitch_joint"], fps_out=50)
    assert out.shape == (expected_frames, 2)
    t_in, t_out = np.arange(frames) / 30.0, np.arange(expected_frames) / 50.0
    for j, column in enumerate([10, 21]):
        np.testing.assert_allclose(out[:, j].numpy(), np.interp(t_out, t_in, data[:, column]), atol=1e-6)


def test_npz_selects_by_name_resamples_and_ignores_other_keys(tmp_path):
    rng = np.random.default_rng(1)
    positions = rng.normal(size=(61, 3))
    path = write_npz(
        tmp_path / "clip.npz", fps=np.array(60), dof_names=np.array(["a_joint", "b_joint", "c_joint"]),
        dof_positions=positions, body_positions=rng.normal(size=(61, 2, 3)),
    )
    same = load_motion(path, ["c_joint", "a_joint"], fps_out=60)
    np.testing.assert_allclose(same.numpy(), positions[:, [2, 0]], atol=1e-6)
    out = load_motion(path, ["b_joint"], fps_out=50)
    assert out.shape == (51, 1)
    np.testing.assert_allclose(out[:, 0].numpy(), np.interp(np.arange(51) / 50, np.arange(61) / 60, positions[:, 1]),
                               atol=1e-6)


def test_csv_with_wrong_column_count(tmp_path):
    path = write_csv(tmp_path / "short.csv", np.zeros((10, 35)))
    with pytest.raises(ValueError, match=r"has 35 columns.*needs 36"):
        load_motion(path, ["left_knee_joint"], 50)


def test_unknown_joint_names_list_the_available_ones(tmp_path):
    path, _ = random_csv(tmp_path)
    with pytest.raises(ValueError, match=r"needs joint\(s\) \['left_toe_joint'\], which the clip does not have.*left_hip_pitch_joint"):
        load_motion(path, ["left_knee_joint", "left_toe_joint"], 50)
    npz = write_npz(tmp_path / "c.npz", fps=30, dof_names=np.array(["x_joint"]), dof_positions=np.zeros((10, 1)))
    with pytest.raises(ValueError, match=r"which the clip does not have; the clip's joints are \['x_joint'\]"):
        load_motion(npz, ["y_joint"], 50)


def test_non_finite_values(tmp_path):
    _, data = random_csv(tmp_path)
    data[4, 10] = np.nan  # left_knee_joint
    path = write_csv(tmp_path / "nan.csv", data)
    with pytest.raises(ValueError, match=r"NaN or inf.*frame 4 of joint 'left_knee_joint'"):
        load_motion(path, ["left_hip_pitch_joint", "left_knee_joint"], 50)
    positions = np.zeros((10, 2))
    positions[7, 1] = np.inf
    npz = write_npz(tmp_path / "inf.npz", fps=30, dof_names=np.array(["a", "b"]), dof_positions=positions)
    with pytest.raises(ValueError, match=r"NaN or inf.*frame 7 of joint 'b'"):
        load_motion(npz, ["b"], 50)


def test_clip_too_short_for_a_window(tmp_path):
    path, _ = random_csv(tmp_path, frames=3)  # 3 frames at 30 fps -> 4 frames at 50 fps
    with pytest.raises(ValueError, match=r"give 4 frames at 50 fps, fewer than min_frames=5"):
        load_motion(path, ["left_knee_joint"], 50)
    assert load_motion(path, ["left_knee_joint"], 50, min_frames=4).shape == (4, 1)


def test_unsupported_extension(tmp_path):
    path = tmp_path / "clip.bvh"
    path.write_text("HIERARCHY\n")
    with pytest.raises(ValueError, match=r"Unsupported motion file extension '\.bvh'.*allowed: \.csv.*\.npz"):
        load_motion(path, ["left_knee_joint"], 50)


def test_missing_npz_key(tmp_path):
    path = write_npz(tmp_path / "clip.npz", fps=30, dof_positions=np.zeros((10, 1)))
    with pytest.raises(ValueError, match=r"lacks the key\(s\) \['dof_names'\]"):
        load_motion(path, ["a"], 50)


def root_pose_clip(frames: int, position, yaw) -> np.ndarray:
    """[frames, 36] a LAFAN1 G1 CSV whose root is at ``position(t)`` [T, 2] with heading ``yaw(t)`` (t in s, 30 fps),
    standing 0.75 m high; joints at zero."""
    t = np.arange(frames) / 30.0
    data = np.zeros((frames, 36))
    data[:, :2], data[:, 2] = position(t), 0.75
    half = yaw(t) / 2
    data[:, 5], data[:, 6] = np.sin(half), np.cos(half)  # quaternion xyzw about z
    return data


@pytest.mark.parametrize("case", ["forward", "sideways", "turning in place"])
def test_root_velocity_is_the_roots_velocity_in_its_heading_frame(tmp_path, case):
    """Walking 0.8 m/s along a heading of 2.5 rad (forward 0.8), stepping 0.3 m/s to the left of a heading of -2 rad
    (sideways 0.3), turning in place at 1.2 rad/s across the +-pi seam (yaw rate 1.2); read at 50 fps from 30."""
    if case == "forward":
        position, yaw, expected = (lambda t: np.outer(t, [0.8 * np.cos(2.5), 0.8 * np.sin(2.5)]),
                                   lambda t: np.full_like(t, 2.5), [0.8, 0.0, 0.0])
    elif case == "sideways":
        left = -2.0 + np.pi / 2
        position, yaw, expected = (lambda t: np.outer(t, [0.3 * np.cos(left), 0.3 * np.sin(left)]),
                                   lambda t: np.full_like(t, -2.0), [0.0, 0.3, 0.0])
    else:
        position, yaw, expected = (lambda t: np.zeros((len(t), 2)), lambda t: 2.8 + 1.2 * t, [0.0, 0.0, 1.2])
    path = write_csv(tmp_path / "root.csv", root_pose_clip(61, position, yaw))
    clip = load_motion(path, ["left_knee_joint"], fps_out=50, with_root_velocity=True)
    assert clip.shape == (101, 4)
    np.testing.assert_allclose(clip[:, 1:].numpy(), np.tile(expected, (101, 1)), atol=1e-4)
    assert (clip[:, 0] == 0).all()


def test_root_velocity_needs_the_clips_root(tmp_path):
    path = write_npz(tmp_path / "no_root.npz", fps=np.array(50.0), dof_names=np.array(["left_knee_joint"]),
                     dof_positions=np.zeros((10, 1)))
    assert load_motion(path, ["left_knee_joint"], fps_out=50).shape == (10, 1)
    with pytest.raises(ValueError, match=r"no_root.npz: the root velocity needs the clip's finite root pose"):
        load_motion(path, ["left_knee_joint"], fps_out=50, with_root_velocity=True)
    rooted = write_npz(tmp_path / "rooted.npz", fps=np.array(50.0), dof_names=np.array(["left_knee_joint"]),
                       dof_positions=np.zeros((10, 1)), root_positions=np.outer(np.arange(10) / 50, [0.5, 0, 0]),
                       root_quaternions=np.tile([0.0, 0.0, 0.0, 1.0], (10, 1)))
    np.testing.assert_allclose(load_motion(rooted, ["left_knee_joint"], fps_out=50, with_root_velocity=True)[:, 1],
                               0.5, atol=1e-5)


def test_load_motions_expands_folders_sorted_and_mixes_with_files(tmp_path):
    folder = tmp_path / "clips"
    folder.mkdir()
    _, b = random_csv(folder, frames=31, name="b.csv", seed=2)
    write_npz(folder / "a.npz", fps=30, dof_names=np.array(["left_knee_joint"]), dof_positions=np.full((31, 1), 7.0))
    (folder / "notes.txt").write_text("not a clip")
    extra, c = random_csv(tmp_path, frames=16, name="extra.csv", seed=3)
    clips = load_motions([folder, extra], ["left_knee_joint"], fps_out=30)
    assert [tuple(c.shape) for c in clips] == [(31, 1), (31, 1), (16, 1)]
    assert torch.all(clips[0] == 7.0)  # a.npz before b.csv
    np.testing.assert_allclose(clips[1][:, 0].numpy(), b[:, 10], atol=1e-6)
    np.testing.assert_allclose(clips[2][:, 0].numpy(), c[:, 10], atol=1e-6)


def test_load_motions_errors_when_nothing_is_found(tmp_path):
    (tmp_path / "readme.txt").write_text("nothing here")
    with pytest.raises(ValueError, match="No motion clips found"):
        load_motions([tmp_path], ["left_knee_joint"], 50)
    with pytest.raises(ValueError, match="No motion clips found"):
        load_motions([], ["left_knee_joint"], 50)


def test_motion_modules_import_without_mujoco():
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] in ('mujoco', 'mujoco_menagerie'):\n"
        "            raise ImportError('mujoco is blocked')\n"
        "sys.meta_path.insert(0, Block())\n"
        "import pchc_rsl.amp, pchc_rsl.amp.motion, pchc_rsl.amp.discriminator\n"
        "print('ok')\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "ok"


# ---------------------------------------------------------------------------------------------------------- windows


def test_windows_are_consecutive_frames_of_one_clip_oldest_first():
    # frame f of clip 0 is (f, -f); of clip 1 (100 + f, -(100 + f)); a window is [q_t, q_t+1, ...] flattened
    clips = [torch.stack([v, -v], dim=-1) for v in (torch.arange(10.0), 100 + torch.arange(7.0))]
    sampler = MotionWindows(clips, window=4)
    out = sampler.sample(500, generator=torch.Generator().manual_seed(0))
    assert out.shape == (500, 8)
    frames = out.reshape(500, 4, 2)
    torch.testing.assert_close(frames[..., 1], -frames[..., 0])
    torch.testing.assert_close(frames[:, 1:, 0] - frames[:, :-1, 0], torch.ones(500, 3))
    first = frames[:, 0, 0]
    valid = ((first >= 0) & (first <= 6)) | ((first >= 100) & (first <= 103))
    assert valid.all()


def test_windows_are_uniform_over_all_valid_starts():
    clips = [torch.arange(10.0)[:, None], 100 + torch.arange(7.0)[:, None]]  # 6 + 3 starts for window 5
    sampler = MotionWindows(clips, window=5)
    assert sampler.num_windows == 9
    first = sampler.sample(90000, generator=torch.Generator().manual_seed(1))[:, 0]
    starts = torch.tensor([0, 1, 2, 3, 4, 5, 100, 101, 102.0])
    counts = (first[:, None] == starts).sum(0).float()
    assert counts.sum() == 90000
    # each start has probability 1/9: 10000 expected, binomial std ~ 94
    assert (counts - 10000).abs().max() < 500, counts


def test_windows_are_reproducible_and_reject_short_clips():
    clips = [torch.randn(20, 3)]
    sampler = MotionWindows(clips, window=5)
    a = sampler.sample(8, generator=torch.Generator().manual_seed(3))
    b = sampler.sample(8, generator=torch.Generator().manual_seed(3))
    assert torch.equal(a, b)
    with pytest.raises(ValueError, match=r"fewer frames than window=5"):
        MotionWindows([torch.randn(20, 3), torch.randn(4, 3)], window=5)
    with pytest.raises(ValueError, match="same J"):
        MotionWindows([torch.randn(20, 3), torch.randn(20, 2)], window=5)


# ---------------------------------------------------------------------------------------------------- discriminator


def sinusoid_windows(n: int, generator: torch.Generator, joints: int = 4, window: int = 5) -> torch.Tensor:
    """Smooth reference motion: each joint a 1.5 Hz sine of random phase and amplitude in [0.5, 1], at 50 fps."""
    t = torch.arange(window) / 50.0
    phase = torch.rand(n, 1, joints, generator=generator) * 2 * math.pi
    amplitude = 0.5 + 0.5 * torch.rand(n, 1, joints, generator=generator)
    return (amplitude * torch.sin(2 * math.pi * 1.5 * t[None, :, None] + phase)).reshape(n, window * joints)


def test_discriminator_separates_reference_from_random_windows():
    torch.manual_seed(0)
    g = torch.Generator().manual_seed(0)
    disc = AMPDiscriminator(20, hidden_dims=[64, 64], input_normalization=True)
    optimizer = torch.optim.Adam(disc.parameters(), lr=1e-3)
    for _ in range(300):
        reference = sinusoid_windows(128, g)
        policy = torch.rand(128, 20, generator=g) * 2 - 1
        disc.update_normalization(torch.cat([reference, policy]))
        loss, info = disc.loss(reference, policy, grad_penalty_coef=1.0)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    assert info["amp/d_ref"] > info["amp/d_policy"]
    with torch.no_grad():
        d_ref = disc(sinusoid_windows(2000, g))
        d_random = disc(torch.rand(2000, 20, generator=g) * 2 - 1)
    assert (d_ref > 0).float().mean() > 0.9
    assert (d_random < 0).float().mean() > 0.9


def constant_discriminator(value: float, input_dim: int = 6) -> AMPDiscriminator:
    """A discriminator whose last layer outputs ``value`` for every input."""
    disc = AMPDiscriminator(input_dim, hidden_dims=[8])
    last = disc.mlp[-1]
    with torch.no_grad():
        last.weight.zero_()
        last.bias.fill_(value)
    return disc


@pytest.mark.parametrize(
    "d, expected",  # 1 - (d - 1)^2 / 4, clipped at 0
    [(1.0, 1.0), (0.0, 0.75), (2.0, 0.75), (0.5, 0.9375), (-1.0, 0.0), (3.0, 0.0), (-2.5, 0.0), (3.5, 0.0)],
)
def test_style_reward_formula_for_a_set_d(d, expected):
    disc = constant_discriminator(d)
    reward = disc.style_reward(torch.randn(5, 6), scale_c=2.0)
    assert reward.shape == (5,)
    torch.testing.assert_close(reward, torch.full((5,), 2.0 * expected))


def test_style_reward_stays_in_range_without_gradients():
    torch.manual_seed(0)
    disc = AMPDiscriminator(10, hidden_dims=[32, 32])
    x = torch.cat([torch.randn(500, 10), 100 * torch.randn(500, 10), torch.zeros(1, 10)]).requires_grad_(True)
    reward = disc.style_reward(x, scale_c=0.5)
    assert not reward.requires_grad
    assert reward.shape == (1001,)
    assert (reward >= 0).all() and (reward <= 0.5).all()


def test_loss_terms_for_a_set_d():
    disc = constant_discriminator(0.25)
    total, info = disc.loss(torch.randn(7, 6), torch.randn(9, 6), grad_penalty_coef=10.0)
    assert info["amp/loss_ref"] == pytest.approx((0.25 - 1) ** 2)
    assert info["amp/loss_policy"] == pytest.approx((0.25 + 1) ** 2)
    assert info["amp/grad_penalty"] == pytest.approx(0.0)  # constant D has zero input gradient
    assert info["amp/d_ref"] == pytest.approx(0.25) and info["amp/d_policy"] == pytest.approx(0.25)
    assert total.item() == pytest.approx(0.5625 + 1.5625)


def reference_grad_penalty(disc: AMPDiscriminator, reference: torch.Tensor) -> float:
    """mean ||dD/dx||^2 w.r.t. the normalised input x = (raw - mean) / (std + eps): the raw gradient * (std + eps)."""
    raw = reference.clone().requires_grad_(True)
    (grad_raw,) = torch.autograd.grad(disc(raw).sum(), raw)
    scale = disc.normalizer.std + disc.normalizer.eps if disc.input_normalization else 1.0
    return (grad_raw * scale).square().sum(-1).mean().item()


@pytest.mark.parametrize("normalization", [False, True])
def test_grad_penalty_is_taken_on_the_reference_batch(normalization):
    torch.manual_seed(0)
    disc = AMPDiscriminator(6, hidden_dims=[16, 16], input_normalization=normalization)
    if normalization:
        disc.update_normalization(torch.randn(256, 6) * torch.tensor([0.1, 1, 3, 0.5, 2, 5]) + 1.0)
    reference, reference2 = torch.randn(32, 6), 2 * torch.randn(32, 6)
    policy, policy2 = torch.randn(16, 6), 3 * torch.randn(16, 6) + 1
    total, info = disc.loss(reference, policy, grad_penalty_coef=5.0)
    expected = reference_grad_penalty(disc, reference)
    assert expected > 1e-4
    assert info["amp/grad_penalty"] == pytest.approx(expected, rel=1e-5)
    assert total.item() == pytest.approx(info["amp/loss_ref"] + info["amp/loss_policy"] + 2.5 * expected, rel=1e-5)

    _, same_reference = disc.loss(reference, policy2, grad_penalty_coef=5.0)
    assert same_reference["amp/grad_penalty"] == pytest.approx(info["amp/grad_penalty"], rel=1e-6)
    assert same_reference["amp/loss_policy"] != pytest.approx(info["amp/loss_policy"], rel=1e-3)
    _, other_reference = disc.loss(reference2, policy, grad_penalty_coef=5.0)
    assert other_reference["amp/grad_penalty"] == pytest.approx(reference_grad_penalty(disc, reference2), rel=1e-5)
    assert other_reference["amp/grad_penalty"] != pytest.approx(info["amp/grad_penalty"], rel=1e-3)


def test_grad_penalty_reaches_the_parameters():
    torch.manual_seed(0)
    disc = AMPDiscriminator(6, hidden_dims=[16])
    reference, policy = torch.randn(32, 6), torch.randn(32, 6)

    def first_layer_grad(coef: float) -> torch.Tensor:
        disc.zero_grad()
        disc.loss(reference, policy, grad_penalty_coef=coef)[0].backward()
        return disc.mlp[0].weight.grad.clone()

    without, with_penalty = first_layer_grad(0.0), first_layer_grad(10.0)
    assert not torch.allclose(without, with_penalty)


def test_discriminator_rejects_wrong_shapes():
    disc = AMPDiscriminator(6, hidden_dims=[8])
    with pytest.raises(ValueError, match=r"reference must be \[B, 6\].*\[4, 5\]"):
        disc.loss(torch.zeros(4, 5), torch.zeros(4, 6), 1.0)
    with pytest.raises(ValueError, match=r"windows must be \[B, 6\]"):
        disc.style_reward(torch.zeros(6), 1.0)


# ---------------------------------------------------------------------------------------------------- replay buffer


def test_replay_buffer_keeps_the_newest_rows():
    buffer = ReplayBuffer(capacity=5, dim=2)
    assert len(buffer) == 0
    with pytest.raises(ValueError, match="empty"):
        buffer.sample(1)
    rows = torch.arange(16.0).reshape(8, 2)  # row i is (2i, 2i + 1)
    buffer.insert(rows[:3])
    assert len(buffer) == 3
    assert set(buffer.sample(200, generator=torch.Generator().manual_seed(0))[:, 0].tolist()) == {0.0, 2.0, 4.0}
    buffer.insert(rows[3:])  # 8 rows inserted in total: rows 3..7 remain
    assert len(buffer) == 5
    sample = buffer.sample(300, generator=torch.Generator().manual_seed(1))
    assert sample.shape == (300, 2)
    torch.testing.assert_close(sample[:, 1], sample[:, 0] + 1)
    assert set((sample[:, 0] / 2).tolist()) == {3.0, 4.0, 5.0, 6.0, 7.0}
    buffer.insert(100 + torch.arange(14.0).reshape(7, 2))  # more than capacity at once: its last 5 rows
    assert set(buffer.sample(300, generator=torch.Generator().manual_seed(2))[:, 0].tolist()) == {
        104.0, 106.0, 108.0, 110.0, 112.0}
    with pytest.raises(ValueError, match=r"expects \[B, 2\]"):
        buffer.insert(torch.zeros(3, 4))


# ------------------------------------------------------------------------------------------------------ integration

WALKING_JOINTS = [
    *G1_CSV_JOINTS[:12],
    "left_shoulder_pitch_joint", "left_shoulder_roll_joint", "left_shoulder_yaw_joint", "left_elbow_joint",
    "right_shoulder_pitch_joint", "right_shoulder_roll_joint", "right_shoulder_yaw_joint", "right_elbow_joint",
]


@pytest.mark.skipif(not os.environ.get("PCHC_MOTION_DIR"), reason="set PCHC_MOTION_DIR to the folder of G1 clips")
def test_real_g1_clips_load_at_50_fps():
    folder = Path(os.environ["PCHC_MOTION_DIR"])
    names = ["fall_and_getup_60fps.npz", "lafan1_walk1_subject1.csv", "walk_60fps.npz"]
    clips = load_motions([folder], WALKING_JOINTS, fps_out=50)
    assert len(clips) == 3 and len(WALKING_JOINTS) == 20
    for name, clip in zip(names, clips):
        path = folder / name
        if path.suffix == ".csv":
            raw = np.loadtxt(path, delimiter=",")
            fps, joints = 30.0, raw[:, 7:]
        else:
            with np.load(path) as data:
                fps, joints = float(data["fps"]), data["dof_positions"]
        frames = joints.shape[0]
        assert clip.shape == (math.floor((frames - 1) * 50 / fps + 1e-9) + 1, 20), name
        assert torch.isfinite(clip).all(), name
        assert clip.abs().max() < 2 * math.pi, name
        # frame 0 is the source's frame 0 (the 20 joints are the first 12 and 15..18, 22..25 of the G1 order)
        columns = [*range(12), 15, 16, 17, 18, 22, 23, 24, 25]
        np.testing.assert_allclose(clip[0].numpy(), joints[0, columns], atol=1e-5)
    windows = MotionWindows(clips, window=5).sample(64, generator=torch.Generator().manual_seed(0))
    assert windows.shape == (64, 100) and torch.isfinite(windows).all()


def test_replay_buffer_state_round_trips_into_a_fresh_buffer():
    buffer = ReplayBuffer(capacity=5, dim=2)
    rows = torch.arange(14.0).reshape(7, 2)
    buffer.insert(rows[:3])
    buffer.insert(rows[3:])  # wraps around: 7 rows written into 5, next write at row 2
    fresh = ReplayBuffer(capacity=5, dim=2)
    fresh.load_state_dict(buffer.state_dict())
    assert len(fresh) == 5 and fresh.position == 2
    torch.testing.assert_close(fresh.data, buffer.data)
    fresh.insert(torch.tensor([[100.0, 101.0]]))
    assert fresh.data[2].tolist() == [100.0, 101.0]  # the oldest row is overwritten, as in the original
    with pytest.raises(ValueError, match="does not fit"):
        ReplayBuffer(capacity=3, dim=2).load_state_dict(buffer.state_dict())


def test_frames_beyond_a_bound_are_left_out_of_the_reference_windows():
    """A 10-frame clip whose joint 'a' leaves +-1.2 rad at frames 4 and 5: of its 8 windows of 3 frames, those
    starting at 0, 1, 6 and 7 hold neither."""
    from pchc_rsl.amp.motion import MotionWindows, kept_frames

    clip = torch.zeros(10, 2)
    clip[4, 0], clip[5, 0] = 1.3, -1.5
    clip[:, 1] = 3.0  # an unbounded joint far from zero changes nothing
    keep = kept_frames(clip, ["a", "b"], {"a": 1.2})
    assert keep.tolist() == [True] * 4 + [False, False] + [True] * 4
    windows = MotionWindows([clip], window=3, keep=[keep])
    assert windows.starts.tolist() == [0, 1, 6, 7]
    assert (windows.sample(200)[:, 0::2].abs() <= 1.2).all()
    with pytest.raises(ValueError, match="not AMP joints"):
        kept_frames(clip, ["a", "b"], {"c": 1.0})
    with pytest.raises(ValueError, match="No reference window"):
        MotionWindows([clip], window=3, keep=[torch.zeros(10, dtype=torch.bool)])


def test_a_clip_outside_the_robots_joint_range_is_refused_naming_file_and_column(tmp_path):
    from pchc_rsl.amp.motion import load_motion

    path = tmp_path / "clip.npz"
    positions = np.zeros((20, 2))
    positions[7, 1] = 2.0
    np.savez(path, fps=30.0, dof_names=np.array(["a", "b"]), dof_positions=positions)
    with pytest.raises(ValueError, match=r"clip\.npz: column 'b' leaves the robot's range \[-1\.000, 1\.000\]") as e:
        load_motion(path, ["a", "b"], 50.0, joint_ranges=[(-1.0, 1.0), (-1.0, 1.0)])
    assert "frame 7" in str(e.value) and "\n" not in str(e.value)
    loaded = load_motion(path, ["a", "b"], 50.0, joint_ranges=[(-1.0, 1.0), (-1.0, 2.01)])
    assert loaded.shape[1] == 2


def test_grad_penalty_on_interpolates_is_taken_between_reference_and_policy_windows():
    """With penalty_on="interpolates" the penalty is the mean squared input gradient at share * ref + (1 - share) *
    policy, share ~ U(0, 1) per pair (drawn from torch's global stream, here reseeded): computed by hand."""
    torch.manual_seed(0)
    disc = AMPDiscriminator(6, hidden_dims=[16, 16], input_normalization=True)
    disc.update_normalization(torch.randn(256, 6) * 2 + 1)
    reference, policy = torch.randn(32, 6), 3 * torch.randn(20, 6) + 1
    torch.manual_seed(5)
    _, info = disc.loss(reference, policy, grad_penalty_coef=5.0, penalty_on="interpolates")
    torch.manual_seed(5)
    share = torch.rand(20, 1)
    at = (share * disc.normalizer(reference[:20]) + (1 - share) * disc.normalizer(policy)).detach().requires_grad_()
    (grad,) = torch.autograd.grad(disc.mlp(at).sum(), at)
    assert info["amp/grad_penalty"] == pytest.approx(grad.square().sum(-1).mean().item(), rel=1e-5)
    assert info["amp/grad_penalty"] != pytest.approx(reference_grad_penalty(disc, reference), rel=1e-2)
    with pytest.raises(ValueError, match="penalty_on 'everywhere'"):
        disc.loss(reference, policy, grad_penalty_coef=5.0, penalty_on="everywhere")


def test_a_loaded_discriminator_trains_at_the_learning_rate_it_is_given(tmp_path):
    """A checkpoint's optimiser state carries its learning rate; a run continued from it with another one (a resume or
    an --init-from with a changed amp_cfg.learning_rate) must step at the new rate: Adam's first steps move each
    weight by about the learning rate, so the same update from the same state moves ten times less at a tenth."""
    from pchc_rsl.amp.style import AMPStyle

    joints = ["a", "b"]
    t = np.arange(60) / 30.0
    write_npz(tmp_path / "clip.npz", fps=30, dof_names=np.array(joints),
              dof_positions=np.stack([np.sin(t), np.cos(t)], axis=1))

    def style(learning_rate):
        torch.manual_seed(0)
        return AMPStyle([str(tmp_path / "clip.npz")], joints, fps=30, input_dim=10, learning_rate=learning_rate,
                        hidden_dims=(8,), num_updates=1, batch_size=16)

    trained = style(1e-4)
    trained.reward(torch.randn(64, 10))
    trained.update()
    saved = trained.state_dict()

    moves = {}
    for learning_rate in (1e-4, 1e-5):
        loaded = style(learning_rate)
        loaded.load_state_dict(saved)
        assert [g["lr"] for g in loaded.optimizer.param_groups] == [learning_rate]
        before = [p.detach().clone() for p in loaded.discriminator.parameters()]
        torch.manual_seed(1)
        loaded.update()
        moves[learning_rate] = max((p - b).abs().max().item()
                                   for p, b in zip(loaded.discriminator.parameters(), before))
    assert moves[1e-4] / moves[1e-5] == pytest.approx(10.0, rel=0.05)


def test_amp_slope_moves_the_joint_columns_of_every_frame_and_never_the_root_velocity():
    from tool_loader import load_tool

    columns = load_tool("studies/amp_slope").sagittal_leg_columns
    names = ["left_hip_pitch_joint", "left_hip_roll_joint", "left_knee_joint"]
    assert columns(names, 2).tolist() == [True, False, True] * 2
    assert columns(names, 2, extra=3).tolist() == [True, False, True, False, False, False] * 2
    every = load_tool("studies/amp_slope").joint_columns
    assert every(names, 2, extra=3).tolist() == [True, True, True, False, False, False] * 2
