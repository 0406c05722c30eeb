"""tools/studies/g1_pci_vs_gated.py: each run's two measures and their paired ratios, against hand-worked values."""

import math

import pytest
from tool_loader import load_tool

study = load_tool("studies/g1_pci_vs_gated")


def run(task_returns, training_reward=1.0):
    rows = [{"preference": [1 - i / 4, i / 4], "task": t, "falls": 1.0, "episode_s": 1.0}
            for i, t in enumerate(task_returns)]
    return {"checkpoint": "x", "per_preference": rows, "training_reward": training_reward}


def test_the_ends_share_is_the_ends_mean_over_the_middle():
    measures = study.run_measures(run([6.0, 9.0, 10.0, 9.0, 2.0]))
    assert measures["mean_task_return"] == pytest.approx(36.0 / 5)
    assert measures["ends_share"] == pytest.approx(4.0 / 10.0)


def test_gate_over_pci_is_the_geometric_mean_of_the_pairs_ratios():
    pci = [run([5, 10, 10, 10, 5], 4.0), run([8, 10, 10, 10, 8], 2.0)]  # ends' shares 0.5, 0.8
    gate = [run([10, 10, 10, 10, 10], 1.0), run([8, 10, 10, 10, 8], 2.0)]  # 1.0, 0.8
    comparison = study.compare(pci, gate)
    assert comparison["ends_share"]["ratio"] == pytest.approx(math.sqrt(2.0 * 1.0))
    assert comparison["mean_task_return"]["ratio"] == pytest.approx(math.sqrt(10.0 / 8.0 * 1.0))
    assert comparison["training_reward"]["ratio"] == pytest.approx(math.sqrt(1.0 / 4.0 * 1.0))


def test_negative_returns_are_compared_by_their_difference():
    comparison = study.compare([run([-1, 1, 1, 1, -1])], [run([1, 1, 1, 1, 1])])  # ends' shares -1 and 1
    assert comparison["ends_share"]["mean_difference"] == pytest.approx(2.0)
    assert comparison["mean_task_return"]["ratio"] == pytest.approx(1.0 / 0.2)
