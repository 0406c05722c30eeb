"""A released policy is small, carries no optimizer or replay state, and still evaluates and resumes."""

import os

import pytest
import torch

from pchc_rsl.cli import eval as eval_cli
from pchc_rsl.cli import runs as runs_cli
from pchc_rsl.cli import train as train_cli
from pchc_rsl.runners.checkpoint import release_checkpoint


def test_release_keeps_the_networks_and_drops_the_training_state():
    saved = {"actor_state_dict": {"w": torch.ones(2)}, "critic_state_dict": {}, "optimizer_state_dict": {"s": 1},
             "training_state": {"torch_rng": torch.zeros(3)}, "config": {"task": "x"}, "iter": 7, "infos": None,
             "amp_state_dict": {"discriminator": {"d": torch.ones(1)}, "optimizer": {}, "replay": {"size": 5}}}
    released = release_checkpoint(saved)
    assert set(released) == {"actor_state_dict", "critic_state_dict", "config", "iter", "amp_state_dict"}
    assert set(released["amp_state_dict"]) == {"discriminator"}
    assert torch.equal(released["actor_state_dict"]["w"], saved["actor_state_dict"]["w"])


def test_a_release_names_files_without_the_folders_of_the_machine_it_was_trained_on():
    config = {"task": "x", "resumed_from": "/home/me/runs/g1/model_520.pt",
              "runner": {"algorithm": {"amp_cfg": {"motion_files": ["/data/motions/g1/walk.csv", "clips/run.npz"]}}},
              "overrides": ['runner.algorithm.amp_cfg.motion_files=["/data/motions/g1/walk.csv"]', "seed=3"],
              "num_envs": 1024}
    released = release_checkpoint({"actor_state_dict": {}, "config": config, "iter": 1})
    assert released["config"] == {
        "task": "x", "resumed_from": "model_520.pt",
        "runner": {"algorithm": {"amp_cfg": {"motion_files": ["walk.csv", "clips/run.npz"]}}},
        "overrides": ['runner.algorithm.amp_cfg.motion_files=["walk.csv"]', "seed=3"], "num_envs": 1024}
    assert config["resumed_from"] == "/home/me/runs/g1/model_520.pt"  # the run's own checkpoint is untouched


def test_a_release_trains_its_whole_actor_when_resumed():
    kwargs = {"routing_scale": 3.0, "trained_experts": [1, 2, 3]}
    config = {"task": "x", "runner": {"actor": {"kwargs": kwargs}}}
    released = release_checkpoint({"actor_state_dict": {}, "config": config, "iter": 1})
    assert released["config"]["runner"]["actor"]["kwargs"] == {"routing_scale": 3.0}
    assert kwargs["trained_experts"] == [1, 2, 3]  # the run's own checkpoint is untouched


def test_a_released_toy_policy_evaluates_and_resumes(tmp_path):
    train_cli.main(["--task", "toy", "--max-iterations", "2", "--log-dir", str(tmp_path / "run")])
    original = tmp_path / "run" / "model_1.pt"
    runs_cli.main(["release", str(original), "--name", "toy", "--out", str(tmp_path / "policies")])
    pt, onnx = str(tmp_path / "policies" / "toy.pt"), str(tmp_path / "policies" / "toy.onnx")
    assert os.path.getsize(pt) < os.path.getsize(original) and os.path.isfile(onnx)
    shipped = torch.load(pt, weights_only=True)
    assert "optimizer_state_dict" not in shipped and shipped["iter"] == 1
    eval_cli.main([pt, "--num-envs", "4", "--episodes", "1", "--preferences", "2", "--output", str(tmp_path / "e")])
    assert (tmp_path / "e" / "table.md").is_file()
    train_cli.main(["--resume", pt, "--max-iterations", "1", "--log-dir", str(tmp_path / "more")])
    resumed = torch.load(tmp_path / "more" / "model_2.pt", weights_only=True)
    assert "optimizer_state_dict" in resumed  # a fresh optimizer, saved from then on


def fall_recovery_checkpoint_trained_for_long(tmp_path):
    """A one-iteration fall-recovery checkpoint whose curriculum reads as if trained for long (assist 0.35, eta's
    step count 20000); skips where the G1 model is unavailable."""
    from test_g1_env import g1_available

    if not g1_available():
        pytest.skip("G1 model unavailable (set MENAGERIE_ROOT)")
    train_cli.main(["--task", "g1-fall-recovery-fast", "--num-envs", "2", "--max-iterations", "1",
                    "runner.num_steps_per_env=4", "--log-dir", str(tmp_path / "run")])
    original = tmp_path / "run" / "model_0.pt"
    saved = torch.load(original, weights_only=True)
    saved["training_state"]["env"].update(assist_level=0.35, global_steps=20000)
    torch.save(saved, original)
    return original


def test_a_released_fall_recovery_policy_resumes_where_its_curriculum_was(tmp_path):
    """The curriculum (assist level, eta's step count) is the env's progress, not a random stream: releasing keeps
    it, so that --resume continues a released policy at the assist and action scale it was trained at."""
    original = fall_recovery_checkpoint_trained_for_long(tmp_path)
    released = release_checkpoint(torch.load(original, weights_only=True))
    assert released["training_state"] == {"env": {"assist_level": 0.35, "global_steps": 20000}}
    runs_cli.main(["release", str(original), "--name", "fall", "--out", str(tmp_path / "policies")])
    pt = str(tmp_path / "policies" / "fall.pt")
    train_cli.main(["--resume", pt, "--max-iterations", "1", "--log-dir", str(tmp_path / "more")])
    env_state = torch.load(tmp_path / "more" / "model_1.pt", weights_only=True)["training_state"]["env"]
    assert env_state["global_steps"] == 20000 + 4  # one iteration of 4 policy steps per env on top
    assert env_state["assist_level"] in (pytest.approx(0.35), pytest.approx(0.30))  # at most one step lower


def test_a_release_is_never_replaced_without_force_and_is_written_whole_or_not_at_all(tmp_path):
    train_cli.main(["--task", "toy", "--max-iterations", "1", "--log-dir", str(tmp_path / "run")])
    original = str(tmp_path / "run" / "model_0.pt")
    out = tmp_path / "policies"

    def release(*args):
        runs_cli.main(["release", original, "--out", str(out), *args])

    release("--name", "toy")
    pt, onnx = out / "toy.pt", out / "toy.onnx"
    before = {path: path.read_bytes() for path in (pt, onnx)}
    with pytest.raises(SystemExit, match="^pchc-runs release: .*exist; give another --name, or --force"):
        release("--name", "toy")
    with pytest.raises(SystemExit, match="^pchc-runs release: .*above --max-mb 0.0001; nothing written"):
        release("--name", "toy", "--force", "--max-mb", "0.0001")
    assert {path: path.read_bytes() for path in (pt, onnx)} == before  # the old release untouched
    with pytest.raises(SystemExit, match="nothing written"):
        release("--name", "new", "--max-mb", "0.0001")
    assert sorted(os.listdir(out)) == ["toy.onnx", "toy.pt"]  # no half release, no scratch folder left
    with pytest.raises(SystemExit, match="^pchc-runs release: --name 'sub/toy': give a file name without folders"):
        release("--name", "sub/toy")
    release("--name", "toy", "--force")


def test_export_onnx_refuses_to_replace_a_file_without_force(tmp_path):
    from pchc_rsl.cli import export_onnx

    train_cli.main(["--task", "toy", "--max-iterations", "1", "--log-dir", str(tmp_path / "run")])
    target = tmp_path / "policy.onnx"
    target.write_text("keep me")
    with pytest.raises(SystemExit, match="exists; give another -o, or --force"):
        export_onnx.main([str(tmp_path / "run" / "model_0.pt"), "-o", str(target)])
    assert target.read_text() == "keep me"
    export_onnx.main([str(tmp_path / "run" / "model_0.pt"), "-o", str(target), "--force"])
    assert target.stat().st_size > 1000


def test_init_from_keeps_the_curriculum_progress_and_not_the_random_streams(tmp_path):
    """--init-from of a fall-recovery checkpoint: a new run (iterations from 0, fresh optimizer) whose curriculum
    continues where the networks were trained (assist 0.35, eta's step count), with the run's own random streams."""
    original = fall_recovery_checkpoint_trained_for_long(tmp_path)
    train_cli.main(["--task", "g1-fall-recovery-fast", "--num-envs", "2", "--max-iterations", "1", "--seed", "5",
                    "runner.num_steps_per_env=4", "--init-from", str(original), "--log-dir", str(tmp_path / "new")])
    new = torch.load(tmp_path / "new" / "model_0.pt", weights_only=True)
    assert new["iter"] == 0 and new["training_state"]["env"]["global_steps"] == 20000 + 4
    saved = torch.load(original, weights_only=True)
    assert not torch.equal(new["training_state"]["env"]["generator"], saved["training_state"]["env"]["generator"])


def test_init_from_a_toy_checkpoint_starts_a_new_run_from_its_weights(tmp_path):
    """--init-from carries the networks and the env's numeric progress only (the toy's per-env positions and its
    random streams stay the new run's own): after one update the actor is still near the checkpoint's, far nearer
    than a fresh run of the same seed."""
    common = ["--task", "toy", "--num-envs", "8", "--max-iterations", "1"]
    train_cli.main([*common, "--log-dir", str(tmp_path / "run")])
    train_cli.main([*common, "--seed", "3", "--init-from", str(tmp_path / "run" / "model_0.pt"),
                    "--log-dir", str(tmp_path / "new")])
    train_cli.main([*common, "--seed", "3", "--log-dir", str(tmp_path / "fresh")])
    actors = {name: torch.load(tmp_path / name / "model_0.pt", weights_only=True)["actor_state_dict"]
              for name in ("run", "new", "fresh")}
    assert torch.load(tmp_path / "new" / "model_0.pt", weights_only=True)["iter"] == 0

    def distance(a, b):
        keys = [k for k, v in actors[a].items() if v.is_floating_point()]
        return sum(float((actors[a][k] - actors[b][k]).pow(2).sum()) for k in keys) ** 0.5

    assert distance("new", "run") < 0.2 * distance("fresh", "run")


def test_resuming_a_release_asks_for_the_clips_it_names_by_file_name(tmp_path, monkeypatch):
    """Before a run folder is made: one line naming the clip and the flag that gives it."""
    saved = torch.load(os.path.join(os.path.dirname(__file__), "..", "policies", "g1_walk.pt"), weights_only=True)
    released = tmp_path / "walker.pt"
    torch.save(release_checkpoint(saved), released)
    monkeypatch.chdir(tmp_path)  # where no clip of that name lies
    with pytest.raises(SystemExit, match=r"names the motion clip \S+\.csv, which is not here; give the clips with "
                                         r"--motion-files\."):
        train_cli.main(["--resume", str(released), "--max-iterations", "1", "--log-dir", str(tmp_path / "more")])
    assert not (tmp_path / "more").exists()
