"""tools/studies/g1_pci_vs_gated.py: each run's measures and their paired ratios, against hand-worked values."""

import math

import pytest
from tool_loader import load_tool

study = load_tool("studies/g1_pci_vs_gated")


def run(task_returns, training_reward=1.0, objectives=None):
    objectives = objectives or [(-1.0, 1.0)] * len(task_returns)
    rows = [{"preference": [1 - i / 4, i / 4], "task": t, "falls": 1.0, "episode_s": 1.0, "disturbance": d,
             "stride": s} for i, (t, (d, s)) in enumerate(zip(task_returns, objectives))]
    return {"checkpoint": "x", "per_preference": rows, "training_reward": training_reward}


def compare(pci, gate, reference=(-2.0, 0.0)):
    return study.compare(*([study.run_measures(r, list(reference)) for r in runs] for runs in (pci, gate)))


def test_the_ends_share_is_the_ends_mean_over_the_middle():
    measures = study.run_measures(run([6.0, 9.0, 10.0, 9.0, 2.0]), [-2.0, 0.0])
    assert measures["mean_task_return"] == pytest.approx(36.0 / 5)
    assert measures["ends_share"] == pytest.approx(4.0 / 10.0)


def test_gate_over_pci_is_the_geometric_mean_of_the_pairs_ratios():
    pci = [run([5, 10, 10, 10, 5], 4.0), run([8, 10, 10, 10, 8], 2.0)]  # ends' shares 0.5, 0.8
    gate = [run([10, 10, 10, 10, 10], 1.0), run([8, 10, 10, 10, 8], 2.0)]  # 1.0, 0.8
    comparison = compare(pci, gate)
    assert comparison["ends_share"]["ratio"] == pytest.approx(math.sqrt(2.0 * 1.0))
    assert comparison["mean_task_return"]["ratio"] == pytest.approx(math.sqrt(10.0 / 8.0 * 1.0))
    assert comparison["training_reward"]["ratio"] == pytest.approx(math.sqrt(1.0 / 4.0 * 1.0))


def test_negative_returns_are_compared_by_their_difference():
    comparison = compare([run([-1, 1, 1, 1, -1])], [run([1, 1, 1, 1, 1])])  # ends' shares -1 and 1
    assert comparison["ends_share"]["mean_difference"] == pytest.approx(2.0)
    assert comparison["mean_task_return"]["ratio"] == pytest.approx(1.0 / 0.2)


def test_the_hypervolume_is_the_area_the_objective_returns_dominate():
    # (-1, 1) and (-3, 2) against the reference (-4, 0): 3 x 1 + 1 x (2 - 1) = 4; (-3.5, 0.5) is dominated
    result = run([1, 1, 1], objectives=[(-1.0, 1.0), (-3.0, 2.0), (-3.5, 0.5)])
    assert study.run_measures(result, [-4.0, 0.0])["hypervolume"] == pytest.approx(4.0)


def test_the_default_reference_point_lies_a_tenth_of_the_spread_below_the_worst_return():
    runs = [run([1, 1], objectives=[(-1.0, 1.0), (-3.0, 2.0)]), run([1, 1], objectives=[(-5.0, 0.0), (-2.0, 3.0)])]
    assert study.reference_point(runs) == pytest.approx([-5.4, -0.3])


def test_the_table_has_a_column_per_objective():
    result = run([1, 2, 3])
    measures = [study.run_measures(result, [-2.0, 0.0])]
    table = study.markdown({"pci": [result], "gate": [result]}, {"pci": measures, "gate": measures},
                           compare([result], [result]), [-2.0, 0.0])
    header, rule, first = table.splitlines()[:3]
    assert header.count("|") == rule.count("|") == first.count("|") == 8  # run, preference, task, 2 objectives, 2
    assert "| (1.00, 0.00) | 1.00 | -1.000 | 1.000 | 100% | 1.00 |" in first
