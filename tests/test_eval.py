import json
import math

import numpy as np
import pytest
import torch

from test_g1_env import pytestmark  # noqa: F401  (skip without the G1 model)

from pchc_rsl.evaluation import WALK_EVALUATION, aggregate, evenly_spaced_preferences, front_summary


def test_aggregate_by_hand():
    episodes = [
        {"stride_length": 0.5, "push_deviation": float("nan"), "fell": 0.0},
        {"stride_length": 0.3, "push_deviation": 0.2, "fell": 1.0},
        {"stride_length": 0.4, "push_deviation": 0.4, "fell": 0.0, "success": 1.0},
    ]
    out = aggregate(episodes)
    assert out["stride_length"] == pytest.approx(0.4)
    assert out["push_deviation"] == pytest.approx(0.3)  # the episode without a push does not count
    assert out["fall_rate"] == pytest.approx(100 / 3)
    assert out["success"] == pytest.approx(100.0)


def test_heading_drift_is_also_reported_as_median_and_90th_percentile():
    """Drifts 1..10 degrees (NaN left out): median 5.5; 90th percentile by linear interpolation 1 + 0.9 x 9 = 9.1."""
    out = aggregate([{"heading_drift": float(v)} for v in [*range(10, 0, -1), float("nan")]])
    assert out["heading_drift"] == pytest.approx(5.5)
    assert out["heading_drift_median"] == pytest.approx(5.5)
    assert out["heading_drift_p90"] == pytest.approx(9.1)
    assert "stride_length_median" not in aggregate([{"stride_length": 0.3}])


def test_aggregate_gives_95_percent_intervals():
    from scipy import stats

    rng = np.random.default_rng(0)
    strides = rng.normal(0.3, 0.05, size=40)
    falls = np.r_[np.ones(4), np.zeros(36)]
    out = aggregate([{"stride_length": s, "fell": f} for s, f in zip(strides, falls)])
    low, high = out["stride_length_ci95"]
    t_low, t_high = stats.t.interval(0.95, len(strides) - 1, loc=strides.mean(), scale=stats.sem(strides))
    assert low == pytest.approx(t_low, rel=1e-6) and high == pytest.approx(t_high, rel=1e-6)
    # falls: the Wilson score interval of 4 / 40, in percent
    z, p, n = stats.norm.ppf(0.975), 0.1, 40
    centre, half = (p + z * z / (2 * n)) / (1 + z * z / n), z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    assert out["fall_rate_ci95"] == pytest.approx([100 * (centre - half), 100 * (centre + half)], rel=1e-6)
    assert out["fall_rate"] == pytest.approx(10.0)


def test_front_summary_by_hand():
    # -deviation and stride (more is better), the paper's order; reference (-2, 0): boxes 1.8 x 0.4 and 1.5 x 0.6
    # overlap 1.5 x 0.4
    points = np.array([[-0.2, 0.4], [-0.5, 0.6], [-0.6, 0.3]])  # the last is dominated
    summary = front_summary(points, WALK_EVALUATION)
    assert summary["num_points"] == 2
    assert summary["hypervolume"] == pytest.approx(0.4 * 1.8 + 0.6 * 1.5 - 0.4 * 1.5)
    assert summary["sparsity"] == pytest.approx((0.2**2 + 0.3**2) / 1)
    assert evenly_spaced_preferences(3) == [(1.0, 0.0), (0.5, 0.5), (0.0, 1.0)]


@pytest.mark.parametrize("task, columns", [
    ("g1-walk-fast", ["Avg. Stride (m)", "Traj. Deviation (m)"]),
    ("g1-fall-recovery-fast", ["Avg. Energy Overall (J/s)", "COM displacement (m)", "Success, mild pushes (%)",
                               "Success, strong pushes (%)"]),
])
def test_eval_cli_writes_the_tables_and_plots(tmp_path, task, columns):
    from pchc_rsl.cli import eval as eval_cli
    from pchc_rsl.cli import train

    train.main(["--task", task, "--num-envs", "2", "--max-iterations", "1", "--log-dir", str(tmp_path / "run")])
    out = tmp_path / "eval"
    args = [str(tmp_path / "run" / "model_0.pt"), "--num-envs", "2", "--episode-length", "0.3", "--preferences", "2",
            "--output", str(out)]
    eval_cli.main(args + ["--switch"])
    table = (out / "table.md").read_text()
    for column in columns:
        assert column in table
    assert table.count("| run/model_0.pt |") == 2
    results = json.loads((out / "results.json").read_text())
    rows = results["results"][0]["rows"]
    assert [r["preference"] for r in rows] == [[1.0, 0.0], [0.0, 1.0]]
    assert "reference_point" in results["results"][0]["front"]
    assert (out / "pareto.png").stat().st_size > 0 and (out / "switching.png").exists()
    # deterministic for a given seed
    eval_cli.main(args[:-1] + [str(tmp_path / "again")])
    again = json.loads((tmp_path / "again" / "results.json").read_text())
    first = [r["metrics"] for r in rows]
    second = [r["metrics"] for r in again["results"][0]["rows"]]
    assert json.dumps(first) == json.dumps(second)
    if "Energy" in columns[0]:
        assert (out / "energy_curve.png").exists()
        assert all(not math.isnan(r["metrics"]["energy_overall"]) for r in rows)


def test_steady_walk_holds_the_command_and_flags_the_measured_steps():
    """settle 0.1 s and measure 0.2 s at dt 0.02: one yield after the reset, then 15 steps, the last 10 measured,
    every step told the command and acted on from the observation the step before returned."""
    from pchc_rsl.evaluation import steady_walk

    class CountingEnv:
        dt, num_envs = 0.02, 1

        def __init__(self):
            self.commands, self.steps, self.told = torch.zeros(1, 3), 0, []

        def set_preference(self, preference):
            self.preference = preference

        def reset(self):
            self.steps = 0

        def get_observations(self):
            return self.steps

        def step(self, action):
            assert action == self.steps  # the policy saw the latest observation
            self.told.append(self.commands.clone())
            self.steps += 1
            return self.steps, None, None, None

    env = CountingEnv()
    flags = [measuring for _, measuring in steady_walk(env, lambda obs: obs, (0.2, 0.8), (0.5, 0.0, 0.3), 0.1, 0.2)]
    assert flags == [False] * 6 + [True] * 10
    assert env.preference == (0.2, 0.8) and env.steps == 15
    assert all(torch.equal(told, torch.tensor([[0.5, 0.0, 0.3]])) for told in env.told)


def test_settle_time_of_a_step_change():
    # 1 before step 100, 2 from it on; trailing 1 s (50-step) average at t >= 100: 1 + (t - 99) / 50. Its range after
    # the switch is 2 - 1.02 = 0.98, so it has settled when 2 - avg <= 0.098, i.e. from t = 145: 0.9 s after.
    # A second objective rewarded only at steps 200-209 (a push response) has no level and is left out.
    from pchc_rsl.evaluation import settle_time

    curve = np.ones((300, 2))
    curve[100:, 0] = 2.0
    curve[:, 1] = 0.0
    curve[200:210, 1] = -1.0
    assert settle_time(curve, 100, 0.02) == pytest.approx(0.9)
    assert math.isnan(settle_time(curve[:, 1:], 100, 0.02))
    assert math.isnan(settle_time(curve, 20, 0.02))  # under 1 s before the switch


def test_every_walking_evaluation_episode_is_commanded_exactly_the_named_command():
    """Walking trains with standing episodes, straight ones (yaw rate zeroed) and ones moving along one axis alone;
    the evaluation commands 0.5 m/s in every episode, and a steering condition its turn in every episode, so that no
    figure mixes in episodes told something else."""
    from pchc_rsl.configs import task_config
    from pchc_rsl.evaluation import evaluation_preset
    from pchc_rsl.training.build import make_env

    cfg = task_config("g1-walk-fast")
    cfg.env.single_axis_probability = 0.3
    shares = (cfg.env.zero_command_probability, cfg.env.zero_yaw_rate_probability, cfg.env.single_axis_probability)
    assert min(shares) > 0  # what the preset has to undo
    cfg = evaluation_preset(cfg, "mild", WALK_EVALUATION)
    cfg.num_envs = 128
    for command in (WALK_EVALUATION.command, (0.5, 0.0, 0.5)):  # the nominal and a robustness turn
        cfg.env.command_ranges = {key: (value, value) for key, value in zip(("lin_vel_x", "lin_vel_y", "ang_vel_z"),
                                                                             command)}
        env = make_env(cfg)
        env.reset()
        torch.testing.assert_close(env.commands, torch.tensor(command).expand(128, 3))


def test_push_presets_are_the_calibrated_speeds_per_task_and_the_v1_ones_stay_by_name():
    from pchc_rsl.configs import task_config
    from pchc_rsl.evaluation import FALL_RECOVERY_EVALUATION, evaluation_preset

    walk = evaluation_preset(task_config("g1-walk-fast"), "strong", WALK_EVALUATION).env.push
    assert (walk.velocity, walk.window_s, walk.interval_s) == ((2.25, 2.25), 1.0, (3.0, 3.0))
    fall = evaluation_preset(task_config("g1-fall-recovery-fast"), "mild", FALL_RECOVERY_EVALUATION).env.push
    assert (fall.velocity, fall.window_s, fall.only_when_standing) == ((2.25, 2.25), 3.0, True)
    old = evaluation_preset(task_config("g1-fall-recovery-fast"), "strong-v1", FALL_RECOVERY_EVALUATION).env.push
    assert (old.velocity, old.window_s) == ((1.2, 1.2), 1.0)
    with pytest.raises(ValueError, match="not one of mild, strong, mild-v1, strong-v1"):
        evaluation_preset(task_config("g1-walk-fast"), "gentle", WALK_EVALUATION)
