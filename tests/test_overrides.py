"""KEY=VALUE overrides of a task's dataclass config: every field reachable, parsed by type, bad keys named."""

import dataclasses

import pytest

from pchc_rsl.cli import train as train_cli
from pchc_rsl.configs import task_config
from pchc_rsl.training.overrides import OverrideError, apply_overrides, config_fields, format_config


def dataclass_leaf_keys(obj, prefix=""):
    """Dotted keys of every non-dataclass field, walking nested dataclasses (independent of the override code)."""
    keys = []
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if dataclasses.is_dataclass(value):
            keys += dataclass_leaf_keys(value, f"{prefix}{f.name}.")
        else:
            keys.append(f"{prefix}{f.name}")
    return keys


def test_every_field_of_the_toy_config_is_listed_and_settable():
    cfg = task_config("toy")
    listed = format_config(cfg)
    expected = [k for k in dataclass_leaf_keys(cfg) if k != "name"]
    for key in expected:
        assert f"\n{key} = " in "\n" + listed, key
    assert set(expected) <= set(config_fields(cfg))


def test_values_are_parsed_against_the_field_types():
    cfg = task_config("toy")
    applied = apply_overrides(cfg, [
        "runner.algorithm.learning_rate=1e-4", "runner.actor.hidden_dims=32,16", "env.goal_a=[2, 0]",
        "runner.algorithm.use_clipped_value_loss=false", "runner.actor.kwargs.history_latent_dim=4",
        "fixed_preference=0.25,0.75", "runner.algorithm.reward_group_names=none", "num_envs=12",
    ])
    assert cfg.runner.algorithm.learning_rate == 0.0001
    assert cfg.runner.actor.hidden_dims == [32, 16]
    assert cfg.env.goal_a == (2.0, 0.0) and isinstance(cfg.env.goal_a[0], float)
    assert cfg.runner.algorithm.use_clipped_value_loss is False
    assert cfg.runner.actor.kwargs["history_latent_dim"] == 4
    assert cfg.fixed_preference == [0.25, 0.75]
    assert cfg.runner.algorithm.reward_group_names is None
    assert cfg.num_envs == 12 and applied[-1] == "num_envs=12"


@pytest.mark.parametrize("override, message", [
    ("runner.algorithm.learning_rat=1", "did you mean 'runner.algorithm.learning_rate'"),
    ("runner.algoritm.gamma=0.9", "did you mean 'runner.algorithm.gamma'"),
    ("num_envs=1.5", "num_envs=1.5: expected int"),
    ("runner.algorithm.gamma=high", "expected float"),
    ("env.goal_a=1,2,3", r"expected tuple\[float, float\] \(2 values\)"),
    ("runner.algorithm", "not a KEY=VALUE"),
    ("runner.algorithm=3", "is a group of settings"),
    ("name=g1-walk", "chosen with --task"),
])
def test_bad_overrides_fail_in_one_line(override, message):
    with pytest.raises(OverrideError, match=message) as error:
        apply_overrides(task_config("toy"), [override])
    assert "\n" not in str(error.value)


def test_g1_reward_terms_are_addressed_by_name():
    cfg = task_config("g1-walk-fast")  # the config only: no model is loaded
    apply_overrides(cfg, ["env.rewards.feet_slip.weight=-0.5", "env.push.interval_s=2,4"])
    term = next(t for t in cfg.env.rewards if t.func.endswith(":feet_slip"))
    assert term.weight == -0.5 and cfg.env.push.interval_s == (2.0, 4.0)


def test_help_with_a_task_lists_its_config(capsys):
    with pytest.raises(SystemExit) as exit_:
        train_cli.main(["--task", "toy", "--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert "runner.algorithm.learning_rate = 0.003  (float)" in out
    assert "env.step_size = 0.15  (float)" in out


def test_show_config_prints_the_resolved_values(capsys):
    train_cli.main(["--task", "toy", "--num-envs", "5", "runner.algorithm.gamma=0.9", "--show-config"])
    out = capsys.readouterr().out
    assert "\nnum_envs = 5  (int)" in out and "\nrunner.algorithm.gamma = 0.9  (float)" in out


def test_a_models_kwargs_take_any_argument_its_class_accepts():
    cfg = task_config("toy")
    assert "trained_experts" not in cfg.runner.actor.kwargs
    apply_overrides(cfg, ["runner.actor.kwargs.trained_experts=[3,4]"])
    assert cfg.runner.actor.kwargs["trained_experts"] == [3, 4]
    with pytest.raises(OverrideError, match="unknown config key 'runner.actor.kwargs.trained_expert'"):
        apply_overrides(cfg, ["runner.actor.kwargs.trained_expert=[3]"])


def test_a_config_saved_under_moved_module_names_restores_as_today():
    """A checkpoint's config names reward terms, the symmetry function and the env class by module path; one saved
    before the envs moved into envs/g1 and envs/physics restores to the config of today's task."""
    import importlib

    from pchc_rsl.configs import task_config
    from pchc_rsl.training.build import restore_config
    from pchc_rsl.training.moved_modules import MOVED_MODULES

    for new in MOVED_MODULES.values():
        importlib.import_module(new)
    old_of = {new: old for old, new in MOVED_MODULES.items()}

    def old_names(value):
        if isinstance(value, dict):
            return {k: old_names(v) for k, v in value.items()}
        if isinstance(value, list):
            return [old_names(v) for v in value]
        if isinstance(value, str) and ":" in value:
            module, _, attribute = value.partition(":")
            return f"{old_of.get(module, module)}:{attribute}"
        return value

    for task in ("g1-walk", "g1-fall-recovery"):
        today = task_config(task).to_dict()
        saved = old_names(today)
        assert "pchc_rsl.envs.g1_rewards:" in str(saved)  # the names a checkpoint saved before the move has
        assert restore_config(saved).to_dict() == today
