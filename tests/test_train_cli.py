"""pchc-train on bad input, on resume, on Ctrl-C and on NaN: one-line errors, no lost or overwritten files."""

import hashlib
import json
import os
import signal
import subprocess
import sys

import pytest
import torch

from pchc_rsl.algorithms import MultiCriticPPO
from pchc_rsl.cli import export_onnx as export_cli
from pchc_rsl.cli import train as train_cli
from pchc_rsl.envs.toy import ToyEnv

SMALL = ["--task", "toy", "--num-envs", "4", "--seed", "3"]


def digest(path):
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


def one_line_exit(capsys, argv, code=None):
    """Run pchc-train expecting it to stop; return its one-line message."""
    with pytest.raises(SystemExit) as exit_:
        train_cli.main(argv)
    err = capsys.readouterr().err.strip()
    message = err or str(exit_.value.code)
    assert "\n" not in message and "Traceback" not in message, message
    if code is not None:  # SystemExit("message") exits with status 1
        assert (1 if isinstance(exit_.value.code, str) else exit_.value.code) == code
    return message


@pytest.mark.parametrize("argv, message", [
    (["--num-envs", "0"], "--num-envs: must be a whole number >= 1, got 0"),
    (["--num-envs", "-1"], "--num-envs: must be a whole number >= 1, got -1"),
    (["--max-iterations", "0"], "--max-iterations: must be a whole number >= 1, got 0"),
    (["--max-iterations", "-5"], "--max-iterations: must be a whole number >= 1"),
    (["--seed", "-1"], "--seed: must be a whole number in"),
    (["--num-envs", "two"], "--num-envs: must be a whole number, got 'two'"),
    (["num_envs=0"], "num_envs must be a whole number >= 1, got 0"),
    (["runner.save_interval=0"], "runner.save_interval must be a whole number >= 1"),
    (["runner.algorithm.learning_rate=nan"], "learning_rate=nan: expected float (a finite number)"),
    (["runner.algorithm.learning_rate=-1"], "learning_rate must be a finite number > 0"),
    (["runner.algorithm.gamma=1.5"], "gamma must be in [0, 1]"),
    (["--fixed-preference", "0.5,0.6"], "sum to 1"),
    (["--fixed-preference", "1,0,0"], "one weight per objective (2 here"),
    (["--device", "tpu"], "device 'tpu'"),
    (["--logger", "mlflow"], "--logger: invalid choice"),
])
def test_bad_arguments_stop_before_any_work(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    assert message in one_line_exit(capsys, ["--task", "toy", *argv])
    assert not os.listdir(tmp_path)  # nothing written, not even an empty logs/


@pytest.mark.skipif(torch.cuda.is_available(), reason="this torch has CUDA")
def test_cuda_on_a_cpu_only_torch_says_so(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert "sees no CUDA GPU; use --device cpu" in one_line_exit(capsys, ["--task", "toy", "--device", "cuda:0"])


def test_warp_physics_without_the_extra_says_what_to_install(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "mujoco_warp", None)  # import mujoco_warp raises ImportError
    message = one_line_exit(capsys, ["--task", "g1-walk-fast", "--physics", "warp"])
    assert "pip install -e \".[warp]\"" in message
    assert not os.listdir(tmp_path)
    assert "applies to the G1 tasks" in one_line_exit(capsys, ["--task", "toy", "--physics", "warp"])


def test_a_run_that_fails_while_starting_leaves_no_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    message = one_line_exit(capsys, [*SMALL, "--max-iterations", "1", "runner.actor.class_name=no_such_module:Actor"])
    assert "no_such_module" in message
    assert not os.listdir(tmp_path)


def test_overrides_shape_the_networks_and_are_saved(tmp_path, capsys):
    run = tmp_path / "run"
    train_cli.main([*SMALL, "--max-iterations", "1", "--log-dir", str(run), "runner.actor.hidden_dims=16,16",
                    "runner.algorithm.gamma=0.9"])
    checkpoint = torch.load(run / "model_0.pt", weights_only=True)
    experts = checkpoint["actor_state_dict"]["mlp.experts.weights.0"]
    assert experts.shape[-1] == 16  # the first expert layer has 16 units instead of the toy's 64
    for config in (checkpoint["config"], json.loads((run / "config.json").read_text())):
        assert config["runner"]["actor"]["hidden_dims"] == [16, 16]
        assert config["runner"]["algorithm"]["gamma"] == 0.9
        assert "runner.algorithm.gamma=0.9" in config["overrides"]


def test_overrides_may_stand_on_both_sides_of_an_option(capsys):
    train_cli.main(["--task", "toy", "runner.algorithm.gamma=0.9", "--actor", "gated", "runner.actor.hidden_dims=16,8",
                    "--seed", "5", "--show-config"])
    shown = capsys.readouterr().out.splitlines()
    assert "runner.algorithm.gamma = 0.9  (float)" in shown
    assert "runner.actor.hidden_dims = [16, 8]  (list[int])" in shown
    assert 'runner.actor.class_name = "pchc_rsl.modules:GatedMoEActor"  (str)' in shown
    assert "seed = 5  (int)" in shown


def test_a_changed_dict_is_listed_by_its_changed_entries_unless_its_keys_changed():
    """Setting one entry lists that entry alone; replacing a dict by one with other keys lists the dict, so the lost
    key shows."""
    one_entry = ({"p": {"x": 1, "y": 2}, "p.x": 1, "p.y": 2}, {"p": {"x": 3, "y": 2}, "p.x": 3, "p.y": 2})
    assert train_cli._most_specific(["p", "p.x"], *one_entry) == ["p.x"]
    lost_key = ({"p": {"x": 1, "y": 2}, "p.x": 1, "p.y": 2}, {"p": {"x": 3}, "p.x": 3})
    assert train_cli._most_specific(["p", "p.x"], *lost_key) == ["p", "p.x"]


def test_a_capped_std_range_bounds_the_noise_of_the_sampled_actions():
    """runner.actor.distribution_cfg.std_range=[1e-6,0.2] caps the toy's initial std (0.3) at 0.2: the spread of
    actions sampled about the mean is 0.2, measured from 20,000 samples."""
    from pchc_rsl.configs import task_config
    from pchc_rsl.training.build import make_runner
    from pchc_rsl.training.overrides import apply_overrides

    spreads = []
    for overrides in ([], ["runner.actor.distribution_cfg.std_range=[1e-6,0.2]"]):
        cfg = task_config("toy")
        apply_overrides(cfg, overrides)
        cfg.num_envs = 20000
        runner = make_runner(cfg)
        obs = runner.env.get_observations()
        actor = runner.alg.actor
        with torch.no_grad():
            spreads.append((actor(obs, stochastic_output=True) - actor(obs)).std().item())
    assert spreads[0] == pytest.approx(0.3, rel=0.03) and spreads[1] == pytest.approx(0.2, rel=0.03)


def test_the_log_is_one_line_per_iteration_and_ends_with_real_commands(tmp_path, capsys):
    run = tmp_path / "run"
    train_cli.main([*SMALL, "--max-iterations", "3", "--log-dir", str(run)])
    out = capsys.readouterr().out
    assert "\x1b" not in out
    lines = [line for line in out.splitlines() if line.startswith("it ")]
    assert [line.split(" | ")[0] for line in lines] == ["it 0/2", "it 1/2", "it 2/2"]
    assert all("reward" in line and "goal_a" in line and "goal_b" in line and "steps/s" in line for line in lines)
    assert f"tensorboard --logdir {run}" in out
    export_line = next(line for line in out.splitlines() if "pchc-export-onnx" in line)
    command = export_line.split("pchc-export-onnx", 1)[1].split()
    export_cli.main(command)  # the printed command works as printed
    assert os.path.isfile(command[-1])
    assert len(out.splitlines()) < 12


def test_checkpoints_get_the_umask_mode(tmp_path):
    umask = os.umask(0)
    os.umask(umask)
    train_cli.main([*SMALL, "--max-iterations", "1", "--log-dir", str(tmp_path / "run")])
    assert (tmp_path / "run" / "model_0.pt").stat().st_mode & 0o777 == 0o666 & ~umask


@pytest.fixture(scope="module")
def gated_run(tmp_path_factory):
    """3 iterations (model_0, model_2) of a gated-actor, fixed-preference baseline."""
    run = tmp_path_factory.mktemp("gated") / "run"
    train_cli.main([*SMALL, "--max-iterations", "3", "--actor", "gated", "--fixed-preference", "0.9,0.1",
                    "runner.save_interval=2", "--log-dir", str(run)])
    return run


def test_resume_takes_the_checkpoints_config_and_continues_in_a_new_folder(gated_run, tmp_path, capsys):
    before = {p.name: digest(p) for p in gated_run.iterdir() if p.is_file()}
    capsys.readouterr()
    train_cli.main(["--resume", str(gated_run / "model_2.pt"), "--max-iterations", "2", "--num-envs", "6",
                    "--log-dir", str(tmp_path / "more")])
    out = capsys.readouterr().out
    assert "overridden: runner.max_iterations 3 -> 2, num_envs 4 -> 6" in out
    assert {p.name: digest(p) for p in gated_run.iterdir() if p.is_file()} == before  # nothing rewritten
    # 3 iterations (0-2) + 2 more = iterations 3 and 4
    assert sorted(p.name for p in (tmp_path / "more").glob("model_*.pt")) == ["model_4.pt"]
    checkpoint = torch.load(tmp_path / "more" / "model_4.pt", weights_only=True)
    assert checkpoint["iter"] == 4
    config = checkpoint["config"]
    assert config["runner"]["actor"]["class_name"] == "pchc_rsl.modules:GatedMoEActor"  # not repeated on resume
    assert config["fixed_preference"] == pytest.approx([0.9, 0.1])
    assert config["num_envs"] == 6 and config["resumed_from"] == str(gated_run / "model_2.pt")


def test_resume_never_writes_into_an_existing_run(gated_run, capsys):
    before = {p.name: digest(p) for p in gated_run.iterdir() if p.is_file()}
    message = one_line_exit(capsys, ["--resume", str(gated_run / "model_2.pt"), "--log-dir", str(gated_run)])
    assert "already holds" in message and "new --log-dir" in message
    assert {p.name: digest(p) for p in gated_run.iterdir() if p.is_file()} == before


def test_a_reused_log_dir_is_refused(gated_run, capsys):
    assert "already holds" in one_line_exit(capsys, [*SMALL, "--log-dir", str(gated_run)])


def interrupt_env_step_after(monkeypatch, calls):
    """Make ToyEnv.step raise KeyboardInterrupt (as Ctrl-C does) at its ``calls``-th call."""
    original = ToyEnv.step
    count = {"n": 0}

    def step(self, actions):
        count["n"] += 1
        if count["n"] == calls:
            raise KeyboardInterrupt
        return original(self, actions)

    monkeypatch.setattr(ToyEnv, "step", step)


def test_ctrl_c_saves_the_last_finished_iteration(tmp_path, monkeypatch, capsys):
    interrupt_env_step_after(monkeypatch, 2 * 20 + 5)  # the toy's rollout is 20 steps: inside iteration 2
    run = tmp_path / "run"
    with pytest.raises(SystemExit) as exit_:
        train_cli.main([*SMALL, "--max-iterations", "10", "--log-dir", str(run)])
    assert exit_.value.code == 130
    assert sorted(p.name for p in run.glob("model_*.pt")) == ["model_0.pt", "model_1.pt"]
    assert torch.load(run / "model_1.pt", weights_only=True)["iter"] == 1
    out = capsys.readouterr().out
    assert f"saved {run / 'model_1.pt'}" in out and "Traceback" not in out
    assert not list(run.glob("*.tmp"))


def test_sigterm_saves_like_ctrl_c_even_in_a_background_job_that_ignores_sigint(tmp_path):
    """A run started with ``&`` by a script has SIGINT ignored; ``kill`` (SIGTERM) must still save and stop."""
    run = tmp_path / "run"
    command = [sys.executable, "-m", "pchc_rsl.cli.train", *SMALL, "--max-iterations", "100000", "--threads", "1",
               "--log-dir", str(run)]
    ignore_sigint = lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)  # noqa: E731  (as a background job)
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                               preexec_fn=ignore_sigint)
    lines = []
    for line in process.stdout:  # wait for iteration 3 to be logged
        lines.append(line)
        if line.startswith("it ") and int(line.split()[1].split("/")[0]) >= 3:
            break
    process.send_signal(signal.SIGTERM)
    out = "".join(lines) + process.stdout.read()
    assert process.wait(timeout=60) == 130, out
    saved = sorted(run.glob("model_*.pt"), key=lambda p: int(p.stem.split("_")[1]))
    assert saved and int(saved[-1].stem.split("_")[1]) >= 3, out
    assert "interrupted; saved" in out and "Traceback" not in out


def test_ctrl_c_before_the_first_iteration_leaves_no_folder(tmp_path, monkeypatch, capsys):
    interrupt_env_step_after(monkeypatch, 3)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit):
        train_cli.main([*SMALL, "--max-iterations", "10"])
    assert not os.listdir(tmp_path)


def test_nan_stops_training_and_keeps_the_last_good_checkpoint(tmp_path, monkeypatch, capsys):
    original = MultiCriticPPO.update
    count = {"n": 0}

    def update(self):
        count["n"] += 1
        losses = original(self)
        if count["n"] == 3:  # iteration 2 diverges
            with torch.no_grad():
                next(self.actor.parameters()).view(-1)[0] = float("nan")
        return losses

    monkeypatch.setattr(MultiCriticPPO, "update", update)
    run = tmp_path / "run"
    message = one_line_exit(capsys, [*SMALL, "--max-iterations", "5", "runner.save_interval=1", "--log-dir", str(run)],
                            code=1)
    assert "diverged at iteration 2" in message and f"last good checkpoint is {run / 'model_1.pt'}" in message
    assert sorted(p.name for p in run.glob("model_*.pt")) == ["model_0.pt", "model_1.pt"]
    weights = torch.load(run / "model_1.pt", weights_only=True)["actor_state_dict"]
    assert all(torch.isfinite(t).all() for t in weights.values())


def test_export_refuses_a_checkpoint_with_nan_weights(gated_run, tmp_path, capsys):
    checkpoint = torch.load(gated_run / "model_2.pt", weights_only=True)
    name = next(k for k, v in checkpoint["actor_state_dict"].items() if v.is_floating_point() and v.dim() > 1)
    checkpoint["actor_state_dict"][name][0] = float("nan")
    torch.save(checkpoint, tmp_path / "nan.pt")
    with pytest.raises(SystemExit, match="NaN or inf"):
        export_cli.main([str(tmp_path / "nan.pt"), "-o", str(tmp_path / "out" / "p.onnx")])
    assert not (tmp_path / "out" / "p.onnx").exists()


def test_export_cli_is_quiet_and_its_file_is_self_contained(gated_run, tmp_path, capfd):
    capfd.readouterr()
    export_cli.main([str(gated_run / "model_2.pt"), "-o", str(tmp_path / "out" / "policy.onnx")])
    out, err = capfd.readouterr()
    assert out == f"pchc-export-onnx: wrote {tmp_path / 'out' / 'policy.onnx'}\n" and err == ""
    assert os.listdir(tmp_path / "out") == ["policy.onnx"]


@pytest.mark.parametrize("content, message", [
    (b"", "is empty (0 bytes)"),
    (None, "is truncated or is not a PyTorch checkpoint"),
    (b"not a checkpoint at all\n", "is damaged or truncated, or not a PyTorch checkpoint"),
    ("tensor", "not an rsl-rl checkpoint"),
])
def test_bad_checkpoint_files_give_one_line_naming_the_file(gated_run, tmp_path, capsys, content, message):
    bad = tmp_path / "bad.pt"
    if content is None:
        whole = (gated_run / "model_2.pt").read_bytes()
        bad.write_bytes(whole[: len(whole) // 2])
    elif content == "tensor":
        torch.save(torch.zeros(3), bad)
    else:
        bad.write_bytes(content)
    from pchc_rsl.cli import eval as eval_cli

    for main, argv in ((train_cli.main, ["--resume", str(bad)]),
                       (export_cli.main, [str(bad), "-o", str(tmp_path / "p.onnx")]),
                       (eval_cli.main, [str(bad), "--output", str(tmp_path / "eval")])):
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        text = str(exit_.value.code)
        assert str(bad) in text and message in text and "\n" not in text, text
    assert sorted(os.listdir(tmp_path)) == ["bad.pt"]  # no output file or folder


@pytest.mark.parametrize("logger, writer", [
    ("tensorboard", None), ("wandb", "WandbLogWriter"), ("neptune", "NeptuneLogWriter")])
def test_loggers_map_to_rsl_rl_log_writers(logger, writer):
    from rsl_rl.utils import resolve_callable

    from pchc_rsl.configs import task_config

    cfg = task_config("toy")
    cfg.runner.logger, cfg.runner.logger_project = logger, "pchc"
    chosen = cfg.runner.to_rsl_rl()["logger"]
    if writer is None:
        assert chosen == "tensorboard"
    else:
        assert resolve_callable(chosen["class_name"]).__name__ == writer and chosen["project_name"] == "pchc"


def test_the_runner_never_replaces_a_checkpoint_it_did_not_write(gated_run, tmp_path):
    from pchc_rsl.configs import task_config
    from pchc_rsl.training.build import make_runner

    with pytest.raises(FileExistsError, match="already holds checkpoints"):
        make_runner(task_config("toy"), str(gated_run))
    cfg = task_config("toy")
    cfg.num_envs = 4
    runner = make_runner(cfg, str(tmp_path / "run"))
    (tmp_path / "run" / "model_0.pt").write_bytes(b"someone else's")
    with pytest.raises(FileExistsError, match="never replaced"):
        runner.learn(1)
    assert (tmp_path / "run" / "model_0.pt").read_bytes() == b"someone else's"


def test_overrides_record_every_change_including_in_place_ones(tmp_path):
    run = tmp_path / "run"
    train_cli.main([*SMALL, "--max-iterations", "1", "--actor", "no-preference", "--fixed-preference", "0.5,0.5",
                    "--log-dir", str(run)])
    overrides = json.loads((run / "config.json").read_text())["overrides"]
    assert 'runner.obs_groups.actor=["policy"]' in overrides
    assert 'runner.actor.class_name="rsl_rl.models:MLPModel"' in overrides
    assert "fixed_preference=[0.5, 0.5]" in overrides


def test_threads_are_set_for_torch_and_the_physics_and_printed(tmp_path, capsys):
    from pchc_rsl.configs import task_config
    from pchc_rsl.training.threads import apply_threads, available_cores

    previous = torch.get_num_threads()
    try:
        cfg = task_config("g1-walk-fast")
        line = apply_threads(cfg, 1)
        assert torch.get_num_threads() == 1 and cfg.env.num_threads == 1
        assert line.startswith("threads: 1 MuJoCo physics while collecting, 1 torch while learning, of ")
        # the default: the physics on every core, torch on one (small networks; spinning OpenMP threads otherwise)
        line = apply_threads(cfg, None)
        assert cfg.env.num_threads == available_cores() and torch.get_num_threads() == 1
        assert line.startswith(f"threads: {available_cores()} MuJoCo physics while collecting, 1 torch")
        toy = task_config("toy")
        assert apply_threads(toy, None).startswith("threads: 1 torch") and torch.get_num_threads() == 1
        assert "expect slowdowns" in apply_threads(toy, available_cores() + 1)
        train_cli.main(["--task", "toy", "--max-iterations", "1", "--threads", "1", "--log-dir", str(tmp_path / "r")])
        assert f"threads: 1 torch, of {available_cores()} cores" in capsys.readouterr().out
    finally:
        torch.set_num_threads(previous)


def test_a_pci_checkpoint_that_predates_the_routing_scale_default_keeps_s_10(tmp_path):
    """Checkpoints saved before the default became 3 do not name routing_scale: they were trained with s = 10."""
    from pchc_rsl.configs import task_config
    from pchc_rsl.training.build import make_runner, restore_config

    fresh = task_config("toy").to_dict()
    assert make_runner(restore_config(fresh)).alg.actor.mlp.scale == 3.0
    old = json.loads(json.dumps(fresh))
    del old["runner"]["actor"]["kwargs"]["routing_scale"]
    assert make_runner(restore_config(old)).alg.actor.mlp.scale == 10.0
    old["runner"]["actor"]["kwargs"]["routing_scale"] = 7.0
    assert make_runner(restore_config(old)).alg.actor.mlp.scale == 7.0


def test_a_checkpoint_saved_before_a_field_existed_runs_with_the_fields_default_not_the_tasks():
    """The walking task now trains with 0-20 ms latency and 15% standing commands; a walker saved before those
    fields existed ran without either, and its restored config must say so (its evaluation did not change)."""
    from pchc_rsl.configs import task_config
    from pchc_rsl.training.build import restore_config

    fresh = task_config("g1-walk-fast")
    assert fresh.env.action_delay_s == (0.0, 0.02) and fresh.env.zero_command_probability == 0.15
    old = json.loads(json.dumps(fresh.to_dict()))
    del old["env"]["action_delay_s"], old["env"]["zero_command_probability"]
    old["env"]["randomization"].pop("num_model_variants")
    restored = restore_config(old)
    assert restored.env.action_delay_s == (0.0, 0.0) and restored.env.zero_command_probability == 0.0
    assert restored.env.randomization.num_model_variants == 64  # nested dataclasses too
    assert tuple(restore_config(fresh.to_dict()).env.action_delay_s) == (0.0, 0.02)  # saved values still win


def _all_tensors(saved: dict, prefix: str = ""):
    for key, value in saved.items():
        if isinstance(value, torch.Tensor):
            yield prefix + str(key), value
        elif isinstance(value, dict):
            yield from _all_tensors(value, f"{prefix}{key}.")


def test_ctrl_c_during_an_update_saves_the_finished_iteration_bit_for_bit_and_resumes_exactly(tmp_path, monkeypatch):
    """Interrupted inside iteration 2's update (its weights and optimizer already moved), the run saves
    model_1.pt as it was when iteration 1 finished: every tensor (networks, Adam state, random streams) equals the
    uninterrupted run's model_1.pt, and 2 resumed iterations equal iterations 2-3 of the uninterrupted run."""
    from pchc_rsl.algorithms import MultiCriticPPO

    args = ["--task", "toy", "--num-envs", "16", "--seed", "3"]
    train_cli.main([*args, "--max-iterations", "4", "runner.save_interval=1", "--log-dir", str(tmp_path / "ref")])
    original, calls = MultiCriticPPO.update, {"n": 0}

    def update_then_interrupt(self):
        calls["n"] += 1
        result = original(self)
        if calls["n"] == 3:  # iteration 2: the update ran, the iteration did not finish
            raise KeyboardInterrupt
        return result

    monkeypatch.setattr(MultiCriticPPO, "update", update_then_interrupt)
    with pytest.raises(SystemExit) as exit_:
        train_cli.main([*args, "--max-iterations", "4", "runner.save_interval=100", "--log-dir", str(tmp_path / "cut")])
    assert exit_.value.code == 130
    monkeypatch.setattr(MultiCriticPPO, "update", original)
    assert sorted(p.name for p in (tmp_path / "cut").glob("model_*.pt")) == ["model_0.pt", "model_1.pt"]
    ref = torch.load(tmp_path / "ref" / "model_1.pt", weights_only=True)
    cut = torch.load(tmp_path / "cut" / "model_1.pt", weights_only=True)
    ref_tensors, cut_tensors = dict(_all_tensors(ref)), dict(_all_tensors(cut))
    assert ref_tensors.keys() == cut_tensors.keys() and cut["iter"] == 1
    for name, tensor in ref_tensors.items():
        assert torch.equal(tensor, cut_tensors[name]), name
    train_cli.main(["--resume", str(tmp_path / "cut" / "model_1.pt"), "--max-iterations", "2",
                    "--log-dir", str(tmp_path / "more")])
    ref3 = torch.load(tmp_path / "ref" / "model_3.pt", weights_only=True)
    more3 = torch.load(tmp_path / "more" / "model_3.pt", weights_only=True)
    for key in ("actor_state_dict", "critic_state_dict"):
        for name, tensor in ref3[key].items():
            assert torch.equal(tensor, more3[key][name]), f"{key}.{name}"


def test_the_continue_line_after_an_interrupt_asks_for_what_is_left(tmp_path, monkeypatch, capsys):
    interrupt_env_step_after(monkeypatch, 2 * 20 + 5)  # inside iteration 2 of 0-9
    with pytest.raises(SystemExit):
        train_cli.main([*SMALL, "--max-iterations", "10", "--log-dir", str(tmp_path / "run")])
    out = capsys.readouterr().out
    assert f"--resume {tmp_path / 'run' / 'model_1.pt'} --max-iterations 8" in out


def test_resume_a_run_folder_takes_its_latest_checkpoint(tmp_path, capsys):
    train_cli.main([*SMALL, "--max-iterations", "3", "runner.save_interval=1", "--log-dir", str(tmp_path / "a")])
    train_cli.main(["--resume", str(tmp_path / "a"), "--max-iterations", "1", "--log-dir", str(tmp_path / "b")])
    assert torch.load(tmp_path / "b" / "model_3.pt", weights_only=True)["iter"] == 3
    assert f"its latest checkpoint, {tmp_path / 'a' / 'model_2.pt'}" in capsys.readouterr().out
    (tmp_path / "empty").mkdir()
    with pytest.raises(SystemExit, match="holds no model_<it>.pt"):
        train_cli.main(["--resume", str(tmp_path / "empty"), "--log-dir", str(tmp_path / "c")])


@pytest.mark.parametrize("argv, message", [
    (["--fixed-preference", "-0.5,1.5"], r"fixed preference \[-0.5, 1.5\]: Preference weights must be >= 0"),
    (["--fixed-preference", "0.3,0.3"], r"got a sum of 0.6 for \[0.3, 0.3\]"),
    (["num_envs=8", "--num-envs", "16"], "num_envs is given twice: --num-envs 16 and num_envs=8"),
    (["seed=1", "seed=2"], "seed is set twice, to 1 and to 2"),
    (["runner.algorithm.learning_rate=nan"], r"learning_rate=nan: expected float \(a finite number\)"),
    (["env.episode_length=inf"], r"expected int"),
])
def test_conflicting_or_non_finite_settings_are_refused_in_one_line(argv, message, tmp_path, capsys):
    with pytest.raises(SystemExit, match=message):
        train_cli.main(["--task", "toy", *argv, "--log-dir", str(tmp_path / "run")])
    assert not (tmp_path / "run").exists()


def test_a_mistyped_task_gets_the_closest_one_and_a_fresh_run_echoes_its_overrides(tmp_path, capsys):
    with pytest.raises(SystemExit, match="Unknown task 'toi'. Did you mean 'toy'?"):
        train_cli.main(["--task", "toi", "--log-dir", str(tmp_path / "x")])
    train_cli.main(["--task", "toy", "--max-iterations", "1", "runner.algorithm.learning_rate=3e-4",
                    "--log-dir", str(tmp_path / "run")])
    line = next(x for x in capsys.readouterr().out.splitlines() if "overrides of the task's config:" in x)
    assert "runner.algorithm.learning_rate=0.0003" in line


def test_a_physics_overflow_stops_training_naming_the_setting_and_keeps_the_checkpoints(tmp_path, monkeypatch, capsys):
    """A MuJoCo Warp buffer that overflows in iteration 2 stops the run in one line: the task, the buffer and the
    size to set (the physics' report), and the last checkpoint, which is whole."""
    from pchc_rsl.utils.physics_overflow import PhysicsOverflow

    reports = {"n": 0}

    def physics_report(self):
        reports["n"] += 1
        if reports["n"] == 3:
            raise PhysicsOverflow("MuJoCo Warp overflowed its buffers of constraint rows (njmax) [NEFC]; set "
                                  "env.warp.constraints_per_env=320 (now 160; needed 161 rows in one world)")
        return {}

    monkeypatch.setattr(ToyEnv, "physics_report", physics_report, raising=False)
    run = tmp_path / "run"
    message = one_line_exit(capsys, [*SMALL, "--max-iterations", "5", "runner.save_interval=1", "--log-dir", str(run)],
                            code=1)
    assert message.startswith("pchc-train: toy: stopped in iteration 2 without learning from it: MuJoCo Warp")
    assert "set env.warp.constraints_per_env=320" in message
    assert f"the last checkpoint, {run / 'model_1.pt'}, is intact" in message
    assert sorted(p.name for p in run.glob("model_*.pt")) == ["model_0.pt", "model_1.pt"]
    assert torch.load(run / "model_1.pt", weights_only=True)["iter"] == 1
