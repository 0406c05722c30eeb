"""pchc-play: videos decoded and counted, the viewer's keys, the viewer itself under Xvfb, and bad input.

Rendering runs in subprocesses: MUJOCO_GL is read when mujoco is imported, which the other tests do first.
"""

import os
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest
import torch

from pchc_rsl.cli import play, play_run
from pchc_rsl.evaluation import TOY_STEPS_PER_SECOND, load_policy
from pchc_rsl.viewers import native

imageio = pytest.importorskip("imageio")


@pytest.fixture(scope="module")
def toy_checkpoint(tmp_path_factory):
    from pchc_rsl.cli import train

    log_dir = tmp_path_factory.mktemp("toy")
    train.main(["--task", "toy", "--num-envs", "8", "--max-iterations", "1", "--log-dir", str(log_dir)])
    return str(log_dir / "model_0.pt")


def run_play(args, **env_vars):
    """pchc-play in a fresh process with these environment variables (None removes one)."""
    env = dict(os.environ)
    for key, value in env_vars.items():
        if value is None:
            env.pop(key, None)
        else:
            env[key] = value
    env.setdefault("OMP_NUM_THREADS", "1")
    return subprocess.run([sys.executable, "-m", "pchc_rsl.cli.play", *args], env=env, capture_output=True,
                          text=True, timeout=300)


@pytest.fixture(scope="module")
def egl():
    probe = subprocess.run(
        [sys.executable, "-c", "import mujoco; mujoco.Renderer(mujoco.MjModel.from_xml_string('<mujoco/>'), 8, 8)"],
        env={**os.environ, "MUJOCO_GL": "egl"}, capture_output=True, text=True, timeout=60)
    if probe.returncode != 0:
        pytest.skip(f"no offscreen OpenGL with MUJOCO_GL=egl: {probe.stderr.strip().splitlines()[-1:]}")


def decode(path):
    """Every frame of a video file, decoded by imageio (ffmpeg for MP4, Pillow for GIF): [T, H, W, 3]."""
    if str(path).endswith(".gif"):
        return np.asarray(imageio.v3.imread(path, index=None))[..., :3]
    reader = imageio.v2.get_reader(path)
    frames = np.stack([frame for frame in reader])
    reader.close()
    return frames


# ---------------------------------------------------------------------------- videos
def test_two_preference_mp4_decodes_with_one_frame_per_step_pair_and_moves(walk_checkpoint, egl, tmp_path):
    out = tmp_path / "walk.mp4"
    result = run_play([walk_checkpoint, "--video", str(out), "--preference", "1,0", "--preference", "0,1",
                       "--seconds", "1", "--width", "64", "--height", "48", "--fps", "25"], MUJOCO_GL="egl")
    assert result.returncode == 0, result.stderr
    frames = decode(out)
    # g1-walk-fast: policy step 4 x 0.005 s = 0.02 s, so 1 s = 50 steps; 25 fps keeps every 2nd step
    assert frames.shape == (25, 48, 2 * 64, 3)
    assert imageio.v2.get_reader(out).get_meta_data()["fps"] == pytest.approx(25.0)
    moved = np.abs(frames[-1].astype(int) - frames[0].astype(int)).mean()
    assert moved > 1.0, "the picture does not change over the episode"
    left, right = frames[0, :, :64].astype(int), frames[0, :, 64:].astype(int)
    assert np.abs(left - right).mean() > 0.5, "the two preferences' tiles are identical"


def test_gif_draws_pushes_as_red_arrows(walk_checkpoint, egl, tmp_path):
    out = tmp_path / "walk.gif"
    result = run_play([walk_checkpoint, "--video", str(out), "--preference", "0.5,0.5", "--seconds", "1",
                       "--width", "160", "--height", "120", "--push-every", "0.3"], MUJOCO_GL="egl")
    assert result.returncode == 0, result.stderr
    frames = decode(out).astype(int)
    assert frames.shape == (25, 120, 160, 3)
    r, g, b = frames[..., 0], frames[..., 1], frames[..., 2]
    red_pixels = ((r > 120) & (r > 2 * g) & (r > 2 * b)).sum(axis=(1, 2))
    # pushes at 0.3, 0.6 and 0.9 s (step 15 = frame 7.5): no arrow before, a clearly visible one after
    assert (red_pixels[:8] == 0).all(), red_pixels
    assert red_pixels[8:].max() > 20, red_pixels


def test_push_arrow_points_along_the_push():
    import mujoco

    from pchc_rsl.envs.g1.render import add_push_arrow

    scene = mujoco.MjvScene(mujoco.MjModel.from_xml_string("<mujoco/>"), maxgeom=10)
    direction = np.array([0.6, -0.8])
    add_push_arrow(scene, np.array([1.0, 2.0, 0.7]), direction)
    assert scene.ngeom == 1
    arrow = scene.geoms[0]
    assert arrow.type == mujoco.mjtGeom.mjGEOM_ARROW
    axis = arrow.mat.reshape(3, 3)[:, 2]  # an arrow points along its frame's z axis
    assert axis == pytest.approx([0.6, -0.8, 0.0], abs=1e-6)
    tip = arrow.pos + arrow.size[2] * axis
    assert np.linalg.norm(tip[:2] - [1.0, 2.0]) < 0.3 and tip[2] == pytest.approx(0.7)  # it ends at the pelvis


def test_eval_video_is_written_next_to_the_tables(walk_checkpoint, egl, tmp_path):
    out = tmp_path / "eval"
    result = subprocess.run(
        [sys.executable, "-m", "pchc_rsl.cli.eval", walk_checkpoint, "--num-envs", "2", "--episode-length", "0.2",
         "--preferences", "2", "--video", "--output", str(out)],
        env={**os.environ, "MUJOCO_GL": "egl", "OMP_NUM_THREADS": "1"}, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert (out / "table.md").exists()
    run = os.path.basename(os.path.dirname(walk_checkpoint))
    frames = decode(out / f"{run}_model_0.mp4")
    assert frames.shape == (5, 240, 2 * 320, 3)  # 0.2 s = 10 policy steps, every 2nd at 25 fps; 320x240 tiles


def test_toy_gif_is_an_animated_plot(toy_checkpoint, tmp_path):
    out = tmp_path / "toy.gif"
    play.main([toy_checkpoint, "--video", str(out), "--preference", "1,0", "--preference", "0,1", "--seconds", "1",
               "--width", "80", "--height", "60"])
    frames = decode(out)
    assert frames.shape == (TOY_STEPS_PER_SECOND, 60, 160, 3)  # one frame per toy step
    assert np.abs(frames[-1].astype(int) - frames[0].astype(int)).sum() > 0


def test_rendering_unavailable_says_which_mujoco_gl_to_try(walk_checkpoint, tmp_path):
    result = run_play([walk_checkpoint, "--video", str(tmp_path / "x.mp4"), "--seconds", "0.1"],
                      MUJOCO_GL="glfw", DISPLAY=None, WAYLAND_DISPLAY=None)
    assert result.returncode != 0
    assert "MUJOCO_GL=egl" in result.stderr and "MUJOCO_GL=osmesa" in result.stderr
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "x.mp4").exists()


# ---------------------------------------------------------------------------- the viewer
def test_keys_move_lambda_push_and_reset(walk_checkpoint):
    _, env, policy = load_policy(walk_checkpoint, 1, 0, 1e6, 0)
    controls = native.LiveControls(env)
    with torch.inference_mode():
        env.set_preference(torch.tensor([0.5, 0.5]))
        for key in (native.RIGHT, native.RIGHT, native.LEFT, native.RIGHT):
            controls.on_key(key)
        controls.on_key(ord("A"))  # not ours: ignored
        from pchc_rsl.export.metadata import COMMAND_COMPONENTS
        from pchc_rsl.viewers.steering import trained_ranges

        before = env.commands[0].clone()
        for key in (native.UP, native.UP, native.PAGE_UP, native.HOME):
            controls.on_key(key)
        assert controls.apply()
        assert env.preference[0].tolist() == pytest.approx([0.3, 0.7])
        ranges = trained_ranges(env.cfg)
        for k, delta in enumerate((0.2, 0.1, 0.1)):  # each clipped to its trained range, untrained ones untouched
            key = COMMAND_COMPONENTS[k]
            expected = min(max(float(before[k]) + delta, ranges[key][0]), ranges[key][1]) if key in ranges else before[k]
            assert float(env.commands[0, k]) == pytest.approx(float(expected), abs=1e-3)
        for _ in range(10):
            controls.on_key(native.RIGHT)
        controls.apply()
        assert env.preference[0].tolist() == pytest.approx([0.0, 1.0])  # stays on the simplex
        obs = env.get_observations()
        assert obs["preference"][0].tolist() == pytest.approx([0.0, 1.0])  # what the policy reads

        obs, *_ = env.step(policy(obs))
        assert not env.pushes.active[0]  # --push-every 0: no push by itself
        controls.on_key(native.SPACE)
        controls.apply()
        before = env.physics.qvel[0, :2].numpy().copy()
        env.step(policy(env.get_observations()))
        assert env.pushes.active[0]
        assert np.linalg.norm(env.physics.qvel[0, :2].numpy() - before) > 0.2  # the pelvis was thrown

        controls.on_key(native.BACKSPACE)
        controls.apply()
        assert int(env.episode_length_buf[0]) == 0 and not env.pushes.active[0]


MUJOCO_GL_AT_IMPORT = """
import os, sys
seen = []
class FirstMujocoImport:
    def find_spec(self, name, path=None, target=None):
        if name == "mujoco" and not seen:
            seen.append(os.environ.get("MUJOCO_GL"))
sys.meta_path.insert(0, FirstMujocoImport())
from pchc_rsl.cli import {command}
try:
    {command}.main({argv})
except SystemExit:
    pass
print(seen)
"""
"""Runs a command on a checkpoint that is not there (it stops once it reads the file) and prints MUJOCO_GL as it was
when mujoco was first imported, which is when MuJoCo reads it."""


@pytest.mark.parametrize("command, video", [("eval", ["--video"]), ("play", ["--video", "x.mp4"])])
def test_without_a_display_video_chooses_egl_before_mujoco_loads(command, video, tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "MUJOCO_GL")}
    cases = [([*video], {}, "['egl']"), ([], {}, "[None]"), ([*video], {"MUJOCO_GL": "glfw"}, "['glfw']"),
             ([*video], {"DISPLAY": ":7"}, "[None]")]
    for flags, extra, expected in cases:
        argv = [str(tmp_path / "missing.pt"), *flags]
        result = subprocess.run([sys.executable, "-c", MUJOCO_GL_AT_IMPORT.format(command=command, argv=argv)],
                                env={**env, **extra}, capture_output=True, text=True, timeout=120, cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        assert result.stdout.strip().splitlines()[-1] == expected, (flags, extra, result.stdout, result.stderr)


def free_display(xvfb):
    """Start Xvfb on a display it chooses itself; returns (process, ':N')."""
    read, write = os.pipe()
    process = subprocess.Popen([xvfb, "-displayfd", str(write), "-screen", "0", "800x600x24", "-nolisten", "tcp"],
                               pass_fds=(write,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write)
    with os.fdopen(read) as f:
        number = f.readline().strip()
    return process, f":{number}"


def test_interactive_viewer_under_xvfb_shows_the_robot_and_closes(walk_checkpoint, tmp_path):
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        pytest.skip("Xvfb is not installed (Debian: apt-get install xvfb)")
    from PIL import ImageGrab

    server, display = free_display(xvfb)
    try:
        env = {**os.environ, "DISPLAY": display, "OMP_NUM_THREADS": "1"}
        env.pop("MUJOCO_GL", None)
        viewer = subprocess.Popen([sys.executable, "-m", "pchc_rsl.cli.play", walk_checkpoint, "--seconds", "4"],
                                  env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        blank = np.asarray(ImageGrab.grab(xdisplay=display))
        shot, deadline = blank, time.time() + 300  # starting takes minutes on a busy 2-core machine
        while viewer.poll() is None and time.time() < deadline:
            time.sleep(1.0)
            shot = np.asarray(ImageGrab.grab(xdisplay=display))
            if shot.std() > 20:
                break
        imageio.v2.imwrite(tmp_path / "viewer.png", shot)
        stdout, stderr = viewer.communicate(timeout=600)
    finally:
        server.terminate()
        server.wait()
    assert blank.std() < 1, "the X screen was not empty before the viewer started"
    assert shot.std() > 20, f"the screenshot stayed blank; viewer stderr: {stderr[-2000:]}"
    assert viewer.returncode == 0, stderr
    assert "viewer closed after 4.0 s" in stdout


# ---------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("args, expected", [
    (["--video", "x.avi"], "must end in .mp4 or .gif"),
    (["--video", "x.mp4", "--width", "63"], "--width 63: a tile size must be an even number"),
    (["--video", "x.mp4", "--preference", "0.5,0.6"], "must sum to 1"),
    (["--video", "x.mp4", "--preference", "a,b"], "expected numbers separated by commas"),
    (["--video", "x.mp4", "--seconds", "0"], "--seconds 0.0: must be > 0"),
])
def test_bad_arguments_say_what_is_allowed(args, expected, capsys):
    with pytest.raises(SystemExit) as error:
        play.main(["model.pt", *args])
    assert expected in str(error.value)


def test_no_display_and_no_video_says_what_to_do(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    with pytest.raises(SystemExit) as error:
        play.main(["model.pt", "--viewer", "native"])
    assert "--viewer web" in str(error.value) and "--video" in str(error.value)


def test_without_a_display_the_viewer_is_the_web_page(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    calls = []
    monkeypatch.setattr(play_run, "watch_in_browser", lambda checkpoint, preference, args: calls.append(checkpoint))
    monkeypatch.setattr(play_run, "watch_checkpoint", lambda *args: pytest.fail("the native viewer needs a display"))
    play.main(["model.pt"])
    assert calls == ["model.pt"]


def test_the_toy_has_no_viewer_but_a_plot(toy_checkpoint, monkeypatch):
    monkeypatch.setenv("DISPLAY", ":0")
    with pytest.raises(SystemExit) as error:
        play.main([toy_checkpoint])
    assert "no MuJoCo scene" in str(error.value) and "--video toy.gif" in str(error.value)


def test_a_preference_of_the_wrong_length_names_the_objectives(toy_checkpoint, tmp_path):
    with pytest.raises(SystemExit) as error:
        play.main([toy_checkpoint, "--video", str(tmp_path / "t.gif"), "--preference", "0.2,0.3,0.5"])
    assert "2 objectives (goal_a, goal_b)" in str(error.value)


def test_a_fixed_preference_checkpoint_is_shown_at_its_preference(tmp_path, monkeypatch):
    """A policy trained at one lambda means nothing at the others: without --preference it is shown at the one it
    was trained at; a --preference given is shown as asked."""
    from pchc_rsl.cli import train

    train.main(["--task", "toy", "--num-envs", "8", "--max-iterations", "1", "--fixed-preference", "0.2,0.8",
                "--log-dir", str(tmp_path / "fixed")])
    checkpoint = str(tmp_path / "fixed" / "model_0.pt")
    shown = []
    monkeypatch.setattr(play_run, "record_checkpoint_video", lambda path, preferences, *rest: shown.append(preferences))
    monkeypatch.setattr(play_run, "watch_in_browser", lambda path, preference, args: shown.append(preference))
    play.main([checkpoint, "--video", str(tmp_path / "t.gif")])
    play.main([checkpoint, "--viewer", "web"])
    play.main([checkpoint, "--video", str(tmp_path / "t.gif"), "--preference", "1,0"])  # asked for: shown
    assert len(shown) == 3 and shown[2] == [(1.0, 0.0)]
    assert len(shown[0]) == 1 and shown[0][0] == pytest.approx((0.2, 0.8)) and shown[1] == pytest.approx((0.2, 0.8))
