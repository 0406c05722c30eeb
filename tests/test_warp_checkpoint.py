"""A policy trained on MuJoCo Warp on a GPU is used anywhere: pchc-eval, pchc-export-onnx and pchc-play on a CPU run
it on C MuJoCo. Trained here on Warp's CPU device, its checkpoint then saying cuda:0 as a GPU run's does."""

import json

import pytest
import torch
from test_g1_env import pytestmark  # noqa: F401  (skip without the G1 model)

pytest.importorskip("mujoco_warp", reason="the warp extra is not installed")


def test_a_warp_trained_checkpoint_evaluates_exports_and_plays_on_c_mujoco(tmp_path):
    import onnxruntime

    from pchc_rsl.cli import eval as eval_cli
    from pchc_rsl.cli import export_onnx, train
    from pchc_rsl.envs.physics.batched_mujoco import BatchedMuJoCo
    from pchc_rsl.evaluation.checkpoint import evaluation_config, load_policy, loaded_policy

    run = tmp_path / "run"
    train.main(["--task", "g1-walk-fast", "--physics", "warp", "--device", "cpu", "--num-envs", "2",
                "--max-iterations", "1", "runner.num_steps_per_env=4", "--log-dir", str(run)])
    checkpoint = run / "model_0.pt"
    saved = torch.load(checkpoint, weights_only=True)
    assert saved["config"]["env"]["physics"] == "warp"
    saved["config"]["device"] = "cuda:0"  # where a GPU run trained
    torch.save(saved, checkpoint)

    cfg = evaluation_config(saved["config"], None, 2, 0)
    assert (cfg.env.physics, cfg.device) == ("mujoco", "cpu")
    assert evaluation_config(saved["config"], None, 2, 0, ["env.physics=warp"]).env.physics == "warp"  # if asked
    runner, policy = loaded_policy(str(checkpoint), cfg)
    assert isinstance(runner.env.physics, BatchedMuJoCo)

    out = tmp_path / "eval"
    eval_cli.main([str(checkpoint), "--num-envs", "2", "--episode-length", "0.3", "--preferences", "2",
                   "--output", str(out)])
    rows = json.loads((out / "results.json").read_text())["results"][0]["rows"]
    assert [r["preference"] for r in rows] == [[1.0, 0.0], [0.0, 1.0]]

    onnx_file = tmp_path / "policy.onnx"
    export_onnx.main([str(checkpoint), "--output", str(onnx_file)])
    session = onnxruntime.InferenceSession(str(onnx_file))
    assert json.loads(session.get_modelmeta().custom_metadata_map["pchc"])["task"] == "g1-walk-fast"

    task, env, play_policy = load_policy(str(checkpoint), 1, 0, 0.3, None)
    assert task == "g1-walk-fast" and isinstance(env.physics, BatchedMuJoCo)
    obs = env.get_observations()
    with torch.inference_mode():
        for _ in range(3):
            obs, *_ = env.step(play_policy(obs))
    assert torch.isfinite(env.robot.joint_pos).all()
