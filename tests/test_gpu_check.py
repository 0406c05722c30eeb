"""The GPU check on a machine without a GPU: it refuses before anything slow, with one verdict line and a summary;
its training-loop step runs as written on Warp's CPU device (slow)."""

import json
import os
import subprocess

import pytest
import torch
from tool_loader import load_tool

ROOT = os.path.join(os.path.dirname(__file__), "..")


@pytest.mark.skipif(torch.cuda.is_available(), reason="a GPU is here: the check would run for minutes")
def test_without_a_gpu_the_check_refuses_in_one_verdict_line_and_writes_its_summary(tmp_path):
    summary = tmp_path / "summary.json"
    result = subprocess.run(["bash", os.path.join(ROOT, "tools", "gpu", "gpu_check.sh"), "--summary", str(summary)],
                            capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert result.returncode == 1
    last = result.stdout.strip().splitlines()[-1]
    assert last.startswith("gpu_check: NOT RUN: the preflight refused") and str(summary) in last
    assert "preflight FAIL" in result.stdout
    written = json.loads(summary.read_text())
    assert written["verdict"] == "NOT RUN" and [s["step"] for s in written["steps"]] == ["0. preflight"]
    assert written["steps"][0]["outcome"] == "refused"


def test_unknown_options_are_named():
    result = subprocess.run(["bash", os.path.join(ROOT, "tools", "gpu", "gpu_check.sh"), "--fast"], capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 2 and "unknown option '--fast'" in result.stdout


@pytest.mark.slow
def test_the_learn_check_runs_runner_learn_on_warp_and_reports_peaks_and_the_step_ratio(tmp_path):
    pytest.importorskip("mujoco_warp", reason="the warp extra is not installed")
    from test_g1_env import g1_available

    if not g1_available():
        pytest.skip("the G1 model is not available (set MENAGERIE_ROOT)")
    out = tmp_path / "learn.json"
    assert load_tool("gpu/gpu_learn_check").main(["--device", "cpu", "--num-envs", "2", "--iterations", "2",
                                              "--json", str(out)]) == 0
    result = json.loads(out.read_text())["results"][0]
    physics = result["physics"]
    assert 0 < physics["max_constraint_rows"] <= physics["constraint_rows_capacity"] == 160
    assert 0 <= physics["solver_limit_share"] <= 100 and result["syncs_per_step"] is None  # no CUDA: not counted
    assert result["env_step_s"] > 0 and 0 < result["env_over_physics"]
