"""What MuJoCo Warp needs of a CUDA machine, checked without one: Warp's view of the driver and toolkit is played by
recorders, so each message and fallback is exercised on any CPU."""

import pytest
import torch

pytest.importorskip("mujoco_warp", reason="the warp extra is not installed")
import warp as wp  # noqa: E402

from pchc_rsl.envs.physics import warp_device  # noqa: E402


def fake_cuda(monkeypatch, devices: int, driver, toolkit=(13, 4), mempool: bool = True) -> None:
    monkeypatch.setattr(wp, "get_cuda_device_count", lambda: devices)
    monkeypatch.setattr(wp, "get_cuda_driver_version", lambda: driver)
    monkeypatch.setattr(wp, "get_cuda_toolkit_version", lambda: toolkit)
    monkeypatch.setattr(wp, "is_mempool_supported", lambda device: mempool)


def test_a_driver_older_than_warps_toolkit_is_named_with_the_wheel_to_install(monkeypatch):
    fake_cuda(monkeypatch, devices=0, driver=(12, 8), toolkit=(13, 4))
    with pytest.raises(RuntimeError) as error:
        warp_device.require_warp_cuda("cuda:0")
    message = str(error.value)
    assert "sees 0 CUDA device(s)" in message and "toolkit 13.4" in message and "driver here is 12.8" in message
    assert f"warp_lang-{wp.__version__}+cu12" in message and "R580" in message


def test_no_driver_and_a_device_index_out_of_range_are_told_apart(monkeypatch):
    fake_cuda(monkeypatch, devices=0, driver=None)
    assert "No CUDA driver was found" in warp_device.warp_cuda_problem("cuda:0")
    fake_cuda(monkeypatch, devices=2, driver=(13, 0))
    assert warp_device.warp_cuda_problem("cuda:1") is None
    assert "cuda:0 .. cuda:1" in warp_device.warp_cuda_problem("cuda:2")


def test_cuda_graphs_only_with_conditional_graphs_and_memory_pools(monkeypatch):
    class Device:
        is_cuda = True

    fake_cuda(monkeypatch, devices=1, driver=(13, 0))
    assert warp_device.cuda_graph_problem(Device()) is None
    fake_cuda(monkeypatch, devices=1, driver=(12, 2), toolkit=(12, 2))
    assert "conditional graphs need CUDA >= 12.4 (driver 12.2, toolkit 12.2)" in warp_device.cuda_graph_problem(Device())
    fake_cuda(monkeypatch, devices=1, driver=(13, 0), mempool=False)
    assert warp_device.cuda_graph_problem(Device()) == "memory pools are not supported"


def test_without_graph_support_the_physics_runs_eagerly(monkeypatch):
    """A CUDA device lacking conditional graphs: every step runs the substeps directly, nothing is captured."""
    from pchc_rsl.envs.physics import warp_mujoco
    from pchc_rsl.robots.g1.constants import WALK_JOINTS
    from pchc_rsl.robots.g1.model import build_g1_model
    from test_g1_env import g1_available

    if not g1_available():
        pytest.skip("the G1 model is not available (set MENAGERIE_ROOT)")
    physics = warp_mujoco.WarpMuJoCo(build_g1_model(list(WALK_JOINTS), 0.005), 2, 4, device="cpu")
    calls = []

    class Device:
        is_cuda = True

    physics.wp_device, physics.eager_reason = Device(), "conditional graphs need CUDA >= 12.4"
    monkeypatch.setattr(physics, "_substeps", lambda: calls.append("substeps"))
    monkeypatch.setattr(wp, "ScopedDevice", lambda device: __import__("contextlib").nullcontext())
    monkeypatch.setattr(wp, "ScopedCapture", lambda *a, **k: calls.append("capture"))
    monkeypatch.setattr(wp, "capture_launch", lambda *a, **k: calls.append("launch"))
    for _ in range(3):
        physics.step(torch.zeros(2, physics.model.nu))
    assert calls == ["substeps"] * 3


def test_an_untested_mujoco_warp_is_named(monkeypatch):
    import importlib.metadata

    monkeypatch.setattr(importlib.metadata, "version", lambda name: "9.9.9")
    note = warp_device.mujoco_warp_version_note()
    assert "9.9.9" in note and f"mujoco-warp=={warp_device.TESTED_MUJOCO_WARP[-1]}" in note
    monkeypatch.setattr(importlib.metadata, "version", lambda name: warp_device.TESTED_MUJOCO_WARP[-1])
    assert warp_device.mujoco_warp_version_note() is None
