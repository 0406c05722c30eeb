import numpy as np
import pytest

from pchc_rsl.pareto import expected_utility, hypervolume, non_dominated, sparsity


def test_non_dominated_drops_dominated_and_duplicate_points():
    points = [[1, 3], [2, 2], [3, 1], [1, 1], [2, 2], [0.5, 3]]
    front = non_dominated(points)
    assert sorted(map(tuple, front)) == [(1, 3), (2, 2), (3, 1)]


def test_hypervolume_of_a_staircase_by_hand():
    # Maximisation with ref (0, 0): union of [0,1]x[0,3], [0,2]x[0,2], [0,3]x[0,1] = 3 + 2 + 1 = 6
    assert hypervolume([[1, 3], [2, 2], [3, 1]], ref=[0, 0]) == pytest.approx(6.0)
    # ref (-1, -1): x in [-1, 1] up to 3 (2x4), [1, 2] up to 2 (1x3), [2, 3] up to 1 (1x2): 8 + 3 + 2 = 13
    assert hypervolume([[1, 3], [2, 2], [3, 1]], ref=[-1, -1]) == pytest.approx(13.0)


def test_hypervolume_ignores_points_that_do_not_dominate_the_reference():
    assert hypervolume([[1, 3], [5, -1]], ref=[0, 0]) == pytest.approx(3.0)
    assert hypervolume([[-1, -1]], ref=[0, 0]) == 0.0


def test_hypervolume_in_three_dimensions_by_hand():
    # Two boxes from the origin: 2x1x1 and 1x2x1 overlap in 1x1x1: 2 + 2 - 1 = 3
    assert hypervolume([[2, 1, 1], [1, 2, 1]], ref=[0, 0, 0]) == pytest.approx(3.0)


def test_sparsity_by_hand():
    # Sorted along objective 1: (0,4), (1,2), (3,1): diffs (1,-2), (2,-1): 1+4+4+1 = 10, over n-1 = 2
    assert sparsity([[3, 1], [0, 4], [1, 2]]) == pytest.approx(5.0)
    assert sparsity([[1, 1]]) == 0.0


def test_metrics_reject_bad_input():
    with pytest.raises(ValueError, match="reference point"):
        hypervolume([[1, 2]], ref=[0, 0, 0])
    with pytest.raises(ValueError, match="finite"):
        sparsity(np.array([[np.nan, 1.0], [1.0, 2.0]]))


def test_expected_utility_by_hand():
    # Ranges: objective 1 in [0, 10], objective 2 in [-100, 0]. Returns normalised:
    # (5, -50) -> (0.5, 0.5); (10, -100) -> (1, 0); (0, 0) -> (0, 1).
    # Utilities: (.5, .5).(0.5, 0.5) = 0.5; (1, 0).(1, 0) = 1; (.25, .75).(0, 1) = 0.75. Mean: 2.25 / 3 = 0.75.
    returns = [[5, -50], [10, -100], [0, 0]]
    preferences = [[0.5, 0.5], [1, 0], [0.25, 0.75]]
    assert expected_utility(returns, preferences, low=[0, -100], high=[10, 0]) == pytest.approx(0.75)
    # The policy that is best at the wrong end for each preference scores 0.
    assert expected_utility([[0, -100], [10, -100]], [[1, 0], [0, 1]], [0, -100], [10, 0]) == 0.0


def test_expected_utility_rejects_bad_ranges_and_shapes():
    with pytest.raises(ValueError, match="high > low"):
        expected_utility([[1, 2]], [[0.5, 0.5]], low=[0, 5], high=[1, 5])
    with pytest.raises(ValueError, match="one preference per row"):
        expected_utility([[1, 2], [3, 4]], [[0.5, 0.5]], low=[0, 0], high=[1, 1])
