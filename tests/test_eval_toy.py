"""pchc-eval on the toy task (no G1 needed): the trade-off table and plot, strict JSON, inputs checked first."""

import json
import math
import os

import pytest
import torch

from pchc_rsl.cli import eval as eval_cli
from pchc_rsl.cli import eval_run
from pchc_rsl.cli import train as train_cli
from pchc_rsl.evaluation import TOY_EVALUATION, format_metric
from pchc_rsl.training.build import make_runner, restore_config


@pytest.fixture(scope="module")
def toy_checkpoint(tmp_path_factory):
    run = tmp_path_factory.mktemp("toy") / "run"
    train_cli.main(["--task", "toy", "--num-envs", "8", "--max-iterations", "2", "--seed", "2", "--log-dir", str(run)])
    return run / "model_1.pt"


def returns_by_hand(checkpoint, preferences, num_envs, seed):
    """Per preference (in order, in one env): mean over envs of each goal's summed reward over one deterministic
    episode (a plain loop)."""
    cfg = restore_config(torch.load(checkpoint, weights_only=True)["config"])
    cfg.num_envs, cfg.seed, cfg.fixed_preference = num_envs, seed, None
    runner = make_runner(cfg)
    runner.load(str(checkpoint))
    policy = runner.get_inference_policy()
    env = runner.env
    out = []
    for preference in preferences:
        sums = torch.zeros(2)
        with torch.inference_mode():
            env.set_preference(preference)
            env.reset()
            obs = env.get_observations()
            for _ in range(env.max_episode_length):
                obs, _, _, extras = env.step(policy(obs))
                sums += extras["reward_groups"][:, 1:].mean(0)
        out.append(sums.tolist())
    return out


def test_eval_writes_the_toy_trade_off(toy_checkpoint, tmp_path, capsys):
    out = tmp_path / "eval"
    eval_cli.main([str(toy_checkpoint), "--num-envs", "4", "--episodes", "1", "--preferences", "3", "--output", str(out)])
    results = json.loads((out / "results.json").read_text(), parse_constant=lambda c: pytest.fail(f"bare {c}"))
    rows = results["results"][0]["rows"]
    assert [r["preference"] for r in rows] == [[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]]
    expected = returns_by_hand(toy_checkpoint, [(1.0, 0.0), (0.5, 0.5), (0.0, 1.0)], 4, 0)
    for row, by_hand in zip(rows, expected):
        assert [row["metrics"]["goal_a"], row["metrics"]["goal_b"]] == pytest.approx(by_hand, rel=1e-5)
    assert "| run/model_1.pt | (0.50, 0.50) |" in (out / "table.md").read_text()
    assert (out / "pareto.png").stat().st_size > 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last == f"pchc-eval: wrote {out / 'results.json'}, {out / 'table.md'}, {out / 'pareto.png'}"
    assert sorted(os.listdir(out)) == ["pareto.png", "results.json", "table.md"]


def test_a_fixed_preference_checkpoint_is_evaluated_at_its_own_preference_only(toy_checkpoint, tmp_path):
    fixed = tmp_path / "fixed"
    train_cli.main(["--task", "toy", "--num-envs", "8", "--max-iterations", "2", "--seed", "2",
                    "--fixed-preference", "0.25,0.75", "--log-dir", str(fixed)])
    out = tmp_path / "eval"
    eval_cli.main([str(toy_checkpoint), str(fixed / "model_1.pt"), "--num-envs", "4", "--episodes", "1",
                   "--preferences", "3", "--output", str(out)])
    pchc, baseline = json.loads((out / "results.json").read_text())["results"]
    assert [r["preference"] for r in pchc["rows"]] == [[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]]
    assert [r["preference"] for r in baseline["rows"]] == [[0.25, 0.75]]
    by_hand = returns_by_hand(fixed / "model_1.pt", [(0.25, 0.75)], 4, 0)[0]
    metrics = baseline["rows"][0]["metrics"]
    assert [metrics["goal_a"], metrics["goal_b"]] == pytest.approx(by_hand, rel=1e-5)
    assert baseline["front"]["num_points"] == 1


@pytest.mark.parametrize("argv, message", [
    (["--num-envs", "0"], "--num-envs: must be a whole number >= 1, got 0"),
    (["--episodes", "0"], "--episodes: must be a whole number >= 1, got 0"),
    (["--episode-length", "0"], "--episode-length: must be a finite number > 0, got 0"),
    (["--episode-length", "nan"], "--episode-length: must be a finite number > 0"),
    (["--preferences", "1"], "--preferences: must be a whole number >= 2"),
    (["--preference", "0.5,0.6"], "--preference 0.5,0.6: Preference weights must sum to 1"),
    (["--preference", "1,0,0"], "--preference 1,0,0: A preference has one weight per objective (2 here"),
    (["--preference", "a,b"], "--preference: must be comma-separated numbers"),
    (["--switch"], "--switch measures falls"),
])
def test_bad_arguments_are_refused_before_any_work(toy_checkpoint, tmp_path, capsys, argv, message):
    with pytest.raises(SystemExit) as exit_:
        eval_cli.main([str(toy_checkpoint), "--output", str(tmp_path / "eval"), *argv])
    text = capsys.readouterr().err.strip() or str(exit_.value.code)
    assert message in text and "\n" not in text
    assert not (tmp_path / "eval").exists()


def test_checkpoints_of_different_tasks_are_refused_before_evaluating(toy_checkpoint, tmp_path, monkeypatch):
    other = torch.load(toy_checkpoint, weights_only=True)
    other["config"]["task"] = "g1-walk"
    torch.save(other, tmp_path / "walk.pt")
    monkeypatch.setattr(eval_run, "evaluate_checkpoint",
                        lambda *a, **k: pytest.fail("evaluated before checking"))
    with pytest.raises(SystemExit, match=r"different tasks \['g1-walk', 'toy'\]"):
        eval_cli.main([str(toy_checkpoint), str(tmp_path / "walk.pt"), "--output", str(tmp_path / "eval")])
    assert not (tmp_path / "eval").exists()


def test_undefined_metrics_are_null_and_an_empty_plot_says_why(tmp_path):
    nan = float("nan")
    rows = [{"preference": [1.0, 0.0], "metrics": {"goal_a": nan, "goal_b": -3.0}},
            {"preference": [0.0, 1.0], "metrics": {"goal_a": nan, "goal_b": float("inf")}}]
    results = [{"name": "run/model_0.pt", "checkpoint": "x", "rows": rows,
                "front": {"hypervolume": 0.0, "sparsity": nan, "reference_point": [-60.0, -60.0], "num_points": 0}}]

    from pchc_rsl.evaluation.plots import _empty_front_reason
    from pchc_rsl.evaluation.report import write_outputs

    written = write_outputs(results, TOY_EVALUATION, {}, None, str(tmp_path / "eval"), 0)
    text = (tmp_path / "eval" / "results.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    saved = json.loads(text)["results"][0]
    assert saved["rows"][0]["metrics"] == {"goal_a": None, "goal_b": -3.0}
    assert saved["front"]["sparsity"] is None
    assert written[-1].endswith("pareto.png")
    reason = _empty_front_reason(results, TOY_EVALUATION)
    assert "goal_a" in reason and "undefined at every preference" in reason
    assert _empty_front_reason([{**results[0], "rows": [
        {"preference": [1.0, 0.0], "metrics": {"goal_a": -1.0, "goal_b": -2.0}}]}], TOY_EVALUATION) == ""
    assert math.isnan(rows[0]["metrics"]["goal_a"])  # the caller's results are not changed


@pytest.mark.parametrize(
    "value, interval, key, digits, expected",
    [
        (0.1234, [0.1, 0.2], "stride_length", 2, "0.12 ± 0.05"),
        (118.04, [116.0, 120.5], "energy_overall", 1, "118.0 ± 2.2"),
        (99.2, [97.2, 99.8], "mild/success", 2, "99.2 [97.2, 99.8]"),  # rates: asymmetric interval
        (0.5, None, "stride_length", 2, "0.50"),
        (0.5, [None, None], "stride_length", 2, "0.50"),  # results.json stores NaN as null
        (0.5, [math.nan, math.nan], "stride_length", 2, "0.50"),
        (math.nan, [0.1, 0.2], "stride_length", 2, "n/a"),
    ],
)
def test_table_cells_show_the_mean_and_the_half_width(value, interval, key, digits, expected):
    assert format_metric(value, interval, key, digits) == expected
