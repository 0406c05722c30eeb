"""The web viewer: lambda from the sliders, the G1 scene, the controls acting on the env, bad input, and end to end in
headless Chromium (the page shows the robot, its slider moves lambda, its push button pushes). Loopback only."""

from __future__ import annotations

import math
import os
import shutil
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from pchc_rsl.viewers.web_page import WebViewerUnavailable, check_port, preference_from_sliders

WALK = "policies/g1_walk.pt"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def g1_available() -> bool:
    from test_g1_env import g1_available as available

    return available()


needs_g1 = pytest.mark.skipif(not g1_available(), reason="G1 model unavailable (set MENAGERIE_ROOT)")


def test_sliders_map_onto_the_simplex():
    assert preference_from_sliders([0.3]) == pytest.approx([0.7, 0.3])  # two objectives: the slider is lambda_2
    assert preference_from_sliders([1.5]) == pytest.approx([0.0, 1.0])  # clipped to the simplex's edge
    assert preference_from_sliders([0.2, 0.2, 0.6]) == pytest.approx([0.2, 0.2, 0.6])
    assert preference_from_sliders([0.5, 0.5, 0.5]) == pytest.approx([1 / 3, 1 / 3, 1 / 3])  # renormalised
    assert preference_from_sliders([0.0, 0.0, 0.0]) == pytest.approx([1 / 3, 1 / 3, 1 / 3])
    assert preference_from_sliders([0.0, 0.9, 0.3]) == pytest.approx([0.0, 0.75, 0.25])


def test_a_port_in_use_is_named_with_a_free_one():
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(WebViewerUnavailable, match=rf"port {port} on 127.0.0.1 is in use.*--port \d+"):
            check_port("127.0.0.1", port)
    check_port("127.0.0.1", port)  # free again


def test_a_missing_viser_names_the_extra(monkeypatch):
    import builtins

    from pchc_rsl.viewers import web_page

    real_import = builtins.__import__

    def no_viser(name, *args, **kwargs):
        if name in ("viser", "mjviser"):
            raise ImportError(f"No module named '{name}'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_viser)
    with pytest.raises(WebViewerUnavailable, match=r'pip install -e "\.\[web\]"'):
        web_page.require_viser()


@pytest.fixture(scope="module")
def walk_viewer():
    """The shipped walker in a web viewer on a free loopback port (no loop running: tests step it)."""
    if not g1_available():
        pytest.skip("G1 model unavailable (set MENAGERIE_ROOT)")
    from pchc_rsl.evaluation import load_policy
    from pchc_rsl.evaluation import TASK_EVALUATION
    from pchc_rsl.viewers.web import WebViewer

    task, env, policy = load_policy(WALK, 1, 0, 1e6, 0.0)  # push only when asked
    viewer = WebViewer(env, policy, [0.5, 0.5], port=free_port(), pushes=TASK_EVALUATION[task].pushes)
    yield viewer
    viewer.close()


@needs_g1
def test_the_scene_holds_every_visible_body_of_the_g1(walk_viewer):
    model = walk_viewer.model
    visible = {int(model.geom_bodyid[g]) for g in range(model.ngeom)
               if model.geom_group[g] <= 2 and model.geom_bodyid[g] != 0 and model.geom_rgba[g, 3] > 0}
    shown = {int(b) for group in walk_viewer.scene._mesh_groups for b in group.body_ids}
    assert visible and visible <= shown
    assert model.body("pelvis").id in shown and model.body("left_ankle_roll_link").id in shown


@needs_g1
def test_the_controls_change_the_env(walk_viewer):
    env = walk_viewer.env
    walk_viewer.preference_sliders[0].value = 0.8  # as the page sets it: the slider's callback queues lambda
    walk_viewer.queue("command", (0, 0.3))
    walk_viewer.queue("pause", True)
    walk_viewer.queue("step")
    walk_viewer.queue("speed", 0.5)
    assert walk_viewer.apply_pending()
    assert env.preference[0].tolist() == pytest.approx([0.2, 0.8])
    assert float(env.commands[0, 0]) == pytest.approx(0.3)
    assert list(walk_viewer.command_sliders) == ["lin_vel_x", "lin_vel_y", "ang_vel_z"]  # the shipped walker steers
    walk_viewer.queue("command", (1, 0.3))
    walk_viewer.queue("command", (2, -5.0))  # past the trained yaw range (-1..1): clipped to it
    walk_viewer.apply_pending()
    assert float(env.commands[0, 1]) == pytest.approx(0.3) and float(env.commands[0, 2]) == pytest.approx(-1.0)
    walk_viewer.queue("command", (1, 0.0))  # back where the page starts (the fixture is shared)
    walk_viewer.queue("command", (2, 0.0))
    walk_viewer.apply_pending()
    assert walk_viewer.paused and walk_viewer.steps_requested == 1 and walk_viewer.speed == 0.5
    assert walk_viewer.obs["preference"][0].tolist() == pytest.approx([0.2, 0.8])  # the policy sees the new lambda
    walk_viewer.preference_sliders[0].value = 0.5  # back where the page starts (the fixture is shared)
    walk_viewer.queue("pause", False)
    walk_viewer.queue("reset")
    walk_viewer.apply_pending()
    assert env.preference[0].tolist() == pytest.approx([0.5, 0.5])
    assert not walk_viewer.paused and int(env.episode_length_buf[0]) == 0


@needs_g1
def test_the_push_button_pushes_at_the_chosen_strength_and_direction(walk_viewer):
    env = walk_viewer.env
    for _ in range(5):
        walk_viewer.step()
    w, x, y, z = env.robot.base_quat[0].tolist()
    heading = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    before = env.physics.qvel[0, :2].clone()
    walk_viewer.queue("push", ("strong", "left"))
    walk_viewer.apply_pending()
    walk_viewer.step()
    expected = np.array([math.cos(heading + math.pi / 2), math.sin(heading + math.pi / 2)])
    np.testing.assert_allclose(env.pushes.direction[0].numpy(), expected, atol=0.05)  # heading moved a little
    gained = float((env.physics.qvel[0, :2] - before).double().numpy() @ expected)
    assert 1.0 < gained < 2.5  # the strong preset is 2.25 m/s; one policy step of physics already slows it
    assert bool(env.pushes.active[0]) and walk_viewer.pushes_done == 1


@needs_g1
def test_the_push_button_pushes_with_a_force_on_a_preset_body(walk_viewer):
    """The force-mild preset: 300-600 N for 0.08 s on the torso or the pelvis, forward; the push's window opens
    and the force acts on that body for four 0.02 s steps, then stops."""
    env = walk_viewer.env
    walk_viewer.step()
    walk_viewer.queue("push", ("force-mild", "forward"))
    walk_viewer.apply_pending()
    walk_viewer.step()
    bodies = {env.model.body(b).id for b in ("torso_link", "pelvis")}
    assert int(env.pushes.force_body[0]) in bodies and bool(env.pushes.active[0])
    assert 300.0 <= float(env.pushes.force[0].norm()) <= 600.0
    applied = env.physics.body_forces[0, :, :3].norm(dim=-1)
    assert float(applied[int(env.pushes.force_body[0])]) == pytest.approx(float(env.pushes.force[0].norm()), rel=1e-5)
    for _ in range(3):
        walk_viewer.step()
    assert float(env.pushes.force_left_s[0]) == 0.0
    walk_viewer.step()
    assert float(env.physics.body_forces[0].abs().sum()) == 0.0


@needs_g1
def test_the_panels_show_rewards_and_gait(walk_viewer):
    for _ in range(10):
        walk_viewer.step()
    walk_viewer._panels()
    columns = walk_viewer.reward_plot.data
    assert len(columns) == 4 and len(columns[0]) == len(walk_viewer.history) > 0  # t, task, 2 objectives
    text = walk_viewer.metrics_text.content
    assert "stride" in text and "pushes" in text and "time" in text


def test_the_toy_gets_its_plot(tmp_path):
    from pchc_rsl.cli import train
    from pchc_rsl.evaluation import load_policy
    from pchc_rsl.viewers.web import WebViewer

    train.main(["--task", "toy", "--num-envs", "2", "--max-iterations", "1", "--log-dir", str(tmp_path / "toy")])
    _, env, policy = load_policy(str(tmp_path / "toy" / "model_0.pt"), 1, 0, None, None)
    viewer = WebViewer(env, policy, [1.0, 0.0], port=free_port())
    try:
        for _ in range(3):
            viewer.step()
        viewer._panels()
        picture = viewer.plot.render(env, 0)
        assert picture.ndim == 3 and picture.std() > 0  # a drawn plot, not a blank image
        assert len(viewer.history) == 3 and "distance to A" in viewer.metrics_text.content
    finally:
        viewer.close()


def play(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pchc_rsl.cli.play", *args], capture_output=True, text=True,
                          timeout=120, env={**os.environ, "DISPLAY": ""})


def test_play_refuses_a_taken_port_and_video_with_viewer_in_one_line():
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = play(WALK, "--viewer", "web", "--port", str(port))
    assert done.returncode != 0 and f"port {port} on 127.0.0.1 is in use" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    done = play(WALK, "--viewer", "web", "--video", "x.mp4")
    assert done.returncode != 0 and "pass one of them" in done.stderr


# ---------------------------------------------------------------------------------------------- in a browser
def browser():
    """Headless Chromium driven by selenium, with Debian's chromium and chromedriver (no driver download)."""
    chromium, driver = shutil.which("chromium"), shutil.which("chromedriver")
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        pytest.skip("selenium missing (pip install -e \".[browser-tests]\")")
    if not (chromium and driver):
        pytest.skip("chromium and chromedriver missing (Debian: apt-get install chromium chromium-driver)")
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for flag in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=960,640",
                 "--use-gl=swiftshader", "--enable-unsafe-swiftshader", "--disable-background-networking"):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(executable_path=driver), options=options)


def wait_for(condition, seconds: float = 30.0) -> bool:
    end = time.time() + seconds
    while time.time() < end:
        if condition():
            return True
        time.sleep(0.2)
    return False


@needs_g1
def test_in_a_browser_the_page_shows_the_robot_and_steers_it(walk_viewer, tmp_path):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    page = browser()
    walk_viewer.queue("pause", True)  # the page loads and is driven while paused: software WebGL redrawing a
    # walking robot 30 times a second leaves a 2-core machine's browser too busy to answer quickly
    stop = threading.Event()
    loop = threading.Thread(target=walk_viewer.run, kwargs={"stop": stop})
    loop.start()
    try:
        page.get(walk_viewer.url)
        assert wait_for(lambda: "Push" in [b.text for b in page.find_elements(By.TAG_NAME, "button")], 60)
        time.sleep(3)  # the meshes arrive and the scene renders
        shot = tmp_path / "page.png" if "PCHC_SCREENSHOT" not in os.environ else Path(os.environ["PCHC_SCREENSHOT"])
        page.save_screenshot(str(shot))
        from PIL import Image

        pixels = np.asarray(Image.open(shot).convert("L"), dtype=float)
        height, width = pixels.shape
        robot = pixels[int(0.3 * height):int(0.65 * height), int(0.45 * width):int(0.55 * width)]  # camera's aim
        floor = pixels[int(0.7 * height):, int(0.05 * width):int(0.3 * width)]
        # the followed robot's dark joints and feet stand in the middle; the floor around is light grey
        assert (robot < 120).mean() > 0.01 > 10 * (floor < 120).mean()

        thumb = page.find_elements(By.CSS_SELECTOR, "[role=slider]")[0]  # the lambda slider, at 0.5
        assert thumb.get_attribute("aria-valuenow") == "0.5"
        thumb.send_keys(Keys.ARROW_RIGHT * 8)  # 0.05 a press, as a user moves it with the keyboard
        assert wait_for(lambda: walk_viewer.env.preference[0].tolist() == pytest.approx([0.1, 0.9], abs=1e-6))

        pushes = walk_viewer.pushes_done
        next(b for b in page.find_elements(By.TAG_NAME, "button") if b.text == "Push").click()
        assert wait_for(lambda: walk_viewer.pushes_done == pushes + 1)
        assert wait_for(lambda: f"pushes: {pushes + 1}" in page.find_element(By.TAG_NAME, "body").text)
        walk_viewer.queue("pause", False)
        assert wait_for(lambda: bool(walk_viewer.env.pushes.active[0]))  # and the robot is pushed once it runs
    finally:
        stop.set()
        loop.join()
        page.quit()
