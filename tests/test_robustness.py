"""Deployment shifts: each condition's overrides reach the env it evaluates, and --robustness writes its report."""

import json

import pytest

from pchc_rsl.evaluation import default_conditions


def test_default_conditions_cover_the_shifts_of_each_task():
    walk = {c.name: c.overrides for c in default_conditions("g1-walk-fast")}
    fall = {c.name: c.overrides for c in default_conditions("g1-fall-recovery")}
    for name in ("nominal", "latency 10 ms", "latency 20 ms", "friction 0.4", "friction 1.2", "pelvis -1 kg",
                 "pelvis +5 kg", "actuators x0.8", "observation noise"):
        assert name in walk and name in fall
    assert "paper physics (2 ms, x10)" in walk and "paper physics (2 ms, x10)" not in fall  # only -fast policies
    assert "command 0 m/s" in walk and "command 1.0 m/s" in walk and "command 0 m/s" not in fall
    assert walk["latency 20 ms"] == ["env.action_delay_s=0.02,0.02"]
    assert [n for n in walk if n.startswith("push")] == ["push 1 m/s", "push 1.5 m/s", "push 2 m/s"]
    assert [n for n in walk if n.startswith("force")] == ["force 300-600 N torso/pelvis", "force 600-900 N torso/pelvis",
                                                         "force 100-300 N legs"]
    assert [n for n in fall if n.startswith("force")] == ["force 300-600 N torso/pelvis",
                                                         "force 700-1000 N torso/pelvis"]


def test_condition_overrides_reach_the_evaluated_env(walk_checkpoint):
    """Built as the evaluation builds them: 20 ms is 4 substeps of 5 ms in every env; friction 0.4, +5 kg and
    x0.8 strength are the model's own values (read from the MjModel, not from the config)."""
    from pchc_rsl.evaluation import evaluation_config
    from pchc_rsl.robots.g1.model import build_g1_model
    from pchc_rsl.runners import load_checkpoint
    from pchc_rsl.training.build import make_env, saved_config

    config = saved_config(walk_checkpoint, load_checkpoint(walk_checkpoint))
    conditions = {c.name: c.overrides for c in default_conditions(config["task"])}
    env = make_env(evaluation_config(config, "mild", 3, 0, conditions["latency 20 ms"]))
    assert env.action_delay.substeps.tolist() == [4, 4, 4]
    nominal = build_g1_model(env.cfg.joints, env.cfg.timestep)
    floor, pelvis = nominal.geom("floor").id, nominal.body("pelvis").id
    for name, check in (
        ("friction 0.4", lambda m: m.geom_friction[floor, 0] == pytest.approx(0.4)),
        ("pelvis +5 kg", lambda m: m.body_mass[pelvis] == pytest.approx(nominal.body_mass[pelvis] + 5.0)),
        ("actuators x0.8", lambda m: m.actuator_gainprm[0, 0] == pytest.approx(0.8 * nominal.actuator_gainprm[0, 0])),
    ):
        env = make_env(evaluation_config(config, "mild", 2, 0, conditions[name]))
        assert all(check(m) for m in env.physics.models), name
    env = make_env(evaluation_config(config, "mild", 2, 0, conditions["command 0 m/s"]))
    assert (env.commands == 0).all()
    env = make_env(evaluation_config(config, "mild", 2, 0, conditions["command 1.0 m/s"]))
    assert env.commands[:, 0].tolist() == [1.0, 1.0]
    env = make_env(evaluation_config(config, "mild", 2, 0, conditions["force 100-300 N legs"]))
    push = env.cfg.push
    assert (push.velocity_share, push.force.share, push.force.magnitude, push.force.duration_s) == (
        0.0, 1.0, (100.0, 300.0), (0.08, 0.08))
    legs = {env.model.body(b).id for b in ("left_knee_link", "right_knee_link", "left_ankle_roll_link",
                                            "right_ankle_roll_link")}
    assert set(env.pushes.force_body_ids.tolist()) == legs and push.interval_s == (3.0, 3.0)


def test_robustness_cli_writes_a_row_per_condition_and_preference(walk_checkpoint, tmp_path):
    from pchc_rsl.cli import eval as eval_cli

    out = tmp_path / "rob"
    eval_cli.main([walk_checkpoint, "--robustness", "--condition", "nominal", "--condition", "latency 20 ms",
                   "--num-envs", "2", "--episodes", "1", "--preferences", "2", "--episode-length", "0.3",
                   "--output", str(out)])
    report = json.loads((out / "robustness.json").read_text())
    assert report["conditions"] == ["nominal", "latency 20 ms"]
    assert [(r["condition"], r["preference"]) for r in report["rows"]] == [
        ("nominal", [1.0, 0.0]), ("nominal", [0.0, 1.0]), ("latency 20 ms", [1.0, 0.0]), ("latency 20 ms", [0.0, 1.0])]
    assert "fall_rate" in report["rows"][0]["metrics"] and "cadence" in report["rows"][0]["metrics"]
    assert "| latency 20 ms |" in (out / "robustness.md").read_text()
    assert (out / "robustness.png").stat().st_size > 1000
    with pytest.raises(SystemExit, match="unknown condition"):
        eval_cli.main([walk_checkpoint, "--robustness", "--condition", "moon gravity", "--output", str(tmp_path / "x")])
    with pytest.raises(SystemExit, match="already holds files"):  # no silent overwrite
        eval_cli.main([walk_checkpoint, "--robustness", "--condition", "nominal", "--output", str(out)])


def test_a_colour_scale_starts_at_zero_so_close_speeds_look_close():
    import numpy as np

    from pchc_rsl.evaluation.robustness import colour_range

    low, high = colour_range("forward_speed", np.array([[0.48, 0.62], [np.nan, 0.55]]))
    assert low == 0.0 and high >= 1.0
    assert (0.62 - 0.48) / (high - low) < 0.15  # 0.48 and 0.62 m/s: neighbours on the scale, not its two ends
    assert colour_range("success", np.array([[97.0, 99.0]])) == (0.0, 100.0)
    assert colour_range("energy_overall", np.array([[220.0, 520.0]])) == (0.0, 520.0)


def test_every_table_names_the_objectives_in_the_tasks_order():
    from pchc_rsl.configs import task_config
    from pchc_rsl.evaluation import TASK_EVALUATION, markdown_table

    for task, evaluation in TASK_EVALUATION.items():
        assert list(evaluation.objectives) == list(task_config(task).env.objective_names), task
    row = {"preference": [1.0, 0.0], "episodes": 1, "metrics": {"goal_a": -1.0, "goal_b": -2.0}}
    table = markdown_table([{"name": "toy", "rows": [row]}], TASK_EVALUATION["toy"])
    assert "| Policy | lambda (goal_a, goal_b) |" in table
