"""The released G1 policies in policies/: small, their ONNX files export the same networks, and the walker does what
its model card reports (it stays up under the mild pushes and strides longer at lambda = (0, 1))."""

import dataclasses
import json
import os

import pytest

from test_g1_env import pytestmark  # noqa: F401  (skip without the G1 model)

POLICIES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "policies")
MAX_MB = 10.0


def shipped(name: str) -> str:
    path = os.path.join(POLICIES, f"{name}.pt")
    if not os.path.exists(path):
        pytest.skip(f"policies/{name}.pt is not shipped")
    return path


@pytest.mark.parametrize("name", ["g1_walk", "g1_fall_recovery"])
def test_shipped_files_are_small_and_the_onnx_is_the_same_policy(name):
    from pchc_rsl.export.onnx_export import check_onnx_against_torch
    from pchc_rsl.runners import load_checkpoint
    from pchc_rsl.training.build import for_running, make_runner, restore_config, saved_config

    pt = shipped(name)
    onnx = os.path.join(POLICIES, f"{name}.onnx")
    for path in (pt, onnx):
        assert os.path.getsize(path) < MAX_MB * 2**20
    saved = load_checkpoint(pt)
    assert "optimizer_state_dict" not in saved
    cfg = for_running(restore_config(saved_config(pt, saved)))
    cfg.num_envs, cfg.device = 1, "cpu"
    runner = make_runner(cfg)
    runner.load(pt)
    module = runner.alg.get_policy().as_onnx(verbose=False).eval()
    assert check_onnx_against_torch(module, onnx, atol=1e-4) <= 1e-4


def test_the_walking_config_fine_tunes_the_shipped_walker():
    """README's fine-tune, `pchc-train --task g1-walk-fast --init-from policies/g1_walk.pt`: the task's config builds
    networks the shipped walker's weights fit, and trains it as it was trained."""
    from pchc_rsl.cli.train import INIT_FROM_PARTS
    from pchc_rsl.configs import task_config
    from pchc_rsl.runners import load_checkpoint
    from pchc_rsl.training.build import make_runner, saved_config

    pt = shipped("g1_walk")
    cfg = task_config("g1-walk-fast")
    cfg.num_envs, cfg.device = 1, "cpu"
    runner = make_runner(cfg)
    runner.load(pt, load_cfg=INIT_FROM_PARTS, widen_critic=True)
    trained = saved_config(pt, load_checkpoint(pt))
    assert trained["runner"]["actor"]["kwargs"] == cfg.runner.actor.kwargs
    # through JSON, so that the saved config's tuples and the dataclass's lists compare alike
    saved_env, current = (json.loads(json.dumps(env)) for env in (trained["env"], dataclasses.asdict(cfg.env)))
    assert {key: current[key] for key in saved_env} == saved_env
    added = {field.name: field.default for field in dataclasses.fields(cfg.env) if field.name not in saved_env}
    assert {key: current[key] for key in added} == added  # options added since the walker trained: off by default


def test_shipped_walker_stays_up_and_strides_longer_at_the_stride_end(tmp_path):
    from pchc_rsl.cli import eval as eval_cli

    pt = shipped("g1_walk")
    # 64 episodes, at most 8 falls at each end (the model card measures 0 of 256 at both)
    eval_cli.main([pt, "--num-envs", "64", "--episodes", "1", "--preference", "1,0", "--preference", "0,1",
                   "--push-presets", "mild", "--output", str(tmp_path)])
    rows = json.loads((tmp_path / "results.json").read_text())["results"][0]["rows"]
    by_preference = {tuple(row["preference"]): row["metrics"] for row in rows}
    stability, stride = by_preference[(1.0, 0.0)], by_preference[(0.0, 1.0)]
    assert stability["fall_rate"] <= 12.5 and stride["fall_rate"] <= 12.5  # at most 8 of 64 episodes
    assert stride["stride_length"] > stability["stride_length"] + 0.03


def test_push_sweep_finds_no_falls_without_a_push_and_all_falls_under_a_huge_one(capsys):
    """tools/diagnostics/push_sweep.py on the shipped fall-recovery policy: a 0 m/s push leaves it standing, a 6 m/s one
    (a sprinter's speed, given in an instant) topples it at both end preferences."""
    from tool_loader import load_tool

    push_sweep = load_tool("diagnostics/push_sweep")
    results = push_sweep.main([shipped("g1_fall_recovery"), "--speeds", "0", "6", "--num-envs", "4",
                               "--preferences", "2", "--window", "3"])["results"]
    for lam in [(1.0, 0.0), (0.0, 1.0)]:
        assert results[lam][0.0]["success"] == 100.0
        assert results[lam][6.0]["success"] == 0.0
    assert "| (1.00, 0.00) | 100.0 [" in capsys.readouterr().out


def test_the_push_calibration_rule_on_a_hand_made_sweep():
    """Fall recovery at (0.5, 0.5): mild is the speed whose COM displacement is nearest the paper's 1.62 m among
    those keeping 90% up (2.0 m/s: 1.5 m; 2.5 m/s is nearer, 1.7 m, but only 85% stay up); strong is the speed
    whose success is nearest 75.7% (2.5 m/s: 85%, against 60% at 3.0)."""
    from tool_loader import load_tool

    choose = load_tool("diagnostics/push_sweep").choose_presets
    sweep = {1.0: {"com_displacement": 0.5, "success": 100.0}, 2.0: {"com_displacement": 1.5, "success": 95.0},
             2.5: {"com_displacement": 1.7, "success": 85.0}, 3.0: {"com_displacement": 2.5, "success": 60.0}}
    assert choose(sweep, "fall", "com_displacement", "success") == (2.0, 2.5)
    walk = {0.5: {"push_deviation": 0.3, "fall_rate": 0.0}, 2.0: {"push_deviation": 1.6, "fall_rate": 30.0}}
    assert choose(walk, "walk", "push_deviation", "fall_rate") == (0.5, 2.0)  # 70% up is nearest 75.7%
