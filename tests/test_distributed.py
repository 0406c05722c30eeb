"""Two training processes on CPU (torchrun, Gloo): identical parameters after updates, different envs per rank."""

import os
import subprocess
import sys

import torch

WORKER = '''
import sys, torch
from pchc_rsl.configs import task_config
from pchc_rsl.training.build import make_runner
from pchc_rsl.utils.distributed import world
cfg = task_config("toy")
cfg.num_envs = 8
runner = make_runner(cfg)
first_obs = runner.env.get_observations()["policy"].clone()
runner.learn(2)
_, rank, _ = world()
torch.save({"actor": runner.alg.actor.state_dict(), "critic": runner.alg.critic.state_dict(),
            "value_normalizer": runner.alg.value_normalizer.state_dict(), "first_obs": first_obs,
            "seed": cfg.seed}, sys.argv[1] + f"/rank{rank}.pt")
'''


def test_two_cpu_processes_keep_identical_parameters(tmp_path):
    script = tmp_path / "worker.py"
    script.write_text(WORKER)
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    result = subprocess.run(
        [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node=2", str(script),
         str(tmp_path)], capture_output=True, text=True, env=env, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    ranks = [torch.load(tmp_path / f"rank{r}.pt", weights_only=True) for r in (0, 1)]
    assert [r["seed"] for r in ranks] == [1, 2]  # each rank its own seed ...
    assert not torch.equal(ranks[0]["first_obs"], ranks[1]["first_obs"])  # ... and its own envs
    for part in ("actor", "critic", "value_normalizer"):
        for name, tensor in ranks[0][part].items():
            assert torch.equal(tensor, ranks[1][part][name]), f"{part}.{name} differs between the ranks"
    # learning happened: the parameters moved away from rank 0's initial ones
    torch.manual_seed(1)
    from pchc_rsl.configs import task_config
    from pchc_rsl.training.build import make_runner

    cfg = task_config("toy")
    cfg.num_envs = 8
    initial = make_runner(cfg).alg.actor.state_dict()
    assert any(not torch.equal(t, ranks[0]["actor"][n]) for n, t in initial.items() if t.is_floating_point())


def test_a_world_that_cannot_start_is_one_line(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("MASTER_ADDR", "MASTER_PORT")}
    env.update(WORLD_SIZE="2", RANK="0", LOCAL_RANK="0", OMP_NUM_THREADS="1")
    result = subprocess.run([sys.executable, "-m", "pchc_rsl.cli.train", "--task", "toy", "--log-dir",
                             str(tmp_path / "run")], capture_output=True, text=True, env=env, timeout=120)
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "could not start the 2-process gloo world as rank 0" in lines[0], result.stderr
    assert "torchrun" in lines[0]
    assert not (tmp_path / "run").exists()


def test_a_gpu_rank_starts_nccl_once_on_the_gpu_of_its_local_rank(monkeypatch):
    """torchrun rank 1 of 2 on cuda:1: the device is set, then one NCCL process group starts (rsl-rl's own setup
    started a second one, which torch refuses). CUDA and the process group are recorders: no GPU needed."""
    import pytest

    from pchc_rsl.runners import PCHCRunner

    calls = []
    monkeypatch.setenv("WORLD_SIZE", "2")
    monkeypatch.setenv("RANK", "1")
    monkeypatch.setenv("LOCAL_RANK", "1")
    monkeypatch.setattr(torch.distributed, "is_available", lambda: True)
    monkeypatch.setattr(torch.distributed, "is_initialized", lambda: any(c[0] == "init" for c in calls))
    monkeypatch.setattr(torch.distributed, "is_nccl_available", lambda: True)
    monkeypatch.setattr(torch.distributed, "init_process_group",
                        lambda backend, rank, world_size: calls.append(("init", backend, rank, world_size)))
    monkeypatch.setattr(torch.cuda, "set_device", lambda index: calls.append(("set_device", index)))
    runner = PCHCRunner.__new__(PCHCRunner)
    runner.device, runner.cfg = "cuda:1", {}
    runner._configure_multi_gpu()
    assert calls == [("set_device", 1), ("init", "nccl", 1, 2)]
    assert runner.cfg["multi_gpu"] == {"global_rank": 1, "local_rank": 1, "world_size": 2}
    assert runner.is_distributed and runner.gpu_local_rank == 1
    calls.clear()
    runner.device = "cuda:0"
    with pytest.raises(ValueError, match="uses the GPU of its local rank, cuda:1"):
        runner._configure_multi_gpu()
    assert calls == []


def test_the_env_is_built_on_the_gpu_of_the_local_rank_set_before_it(monkeypatch):
    """torchrun rank 1 on CUDA: make_runner makes cuda:1 the current device before the env exists (its physics may
    allocate on the GPU), and the env and runner are given cuda:1. CUDA and the builders are recorders."""
    from pchc_rsl.configs import task_config
    from pchc_rsl.training import build

    calls = []
    monkeypatch.setenv("WORLD_SIZE", "2")
    monkeypatch.setenv("RANK", "1")
    monkeypatch.setenv("LOCAL_RANK", "1")
    monkeypatch.setattr(torch.cuda, "set_device", lambda index: calls.append(("set_device", index)))
    monkeypatch.setattr(build, "make_env", lambda cfg: calls.append(("env", cfg.device)) or "env")
    monkeypatch.setattr(build, "PCHCRunner", lambda env, train_cfg, log_dir, device, config, verbose: calls.append(
        ("runner", device)))
    cfg = task_config("toy")
    cfg.device = "cuda"
    build.make_runner(cfg)
    assert calls == [("set_device", 1), ("env", "cuda:1"), ("runner", "cuda:1")]


def test_a_gpu_run_saves_and_restores_its_own_gpus_random_stream_only(monkeypatch):
    from pchc_rsl.runners import PCHCRunner

    reads = []
    monkeypatch.setattr(torch.cuda, "get_rng_state", lambda device: reads.append(device) or torch.tensor([7]))
    monkeypatch.setattr(torch.cuda, "get_rng_state_all", lambda: reads.append("all"))
    runner = PCHCRunner.__new__(PCHCRunner)
    runner.device, runner.env = "cuda:1", object()
    assert torch.equal(runner.training_state()["cuda_rng"], torch.tensor([7])) and reads == ["cuda:1"]
    restored = []
    monkeypatch.setattr(torch.cuda, "set_rng_state", lambda state, device: restored.append((state.tolist(), device)))
    runner.restore_training_state({"training_state": {"cuda_rng": torch.tensor([7])}})
    runner.restore_training_state({"training_state": {"cuda_rng": [torch.tensor([5]), torch.tensor([6])]}})  # older
    assert restored == [([7], "cuda:1"), ([6], "cuda:1")]


def test_training_leaves_the_process_group(monkeypatch):
    from pchc_rsl.utils import distributed

    calls = []
    monkeypatch.setattr(torch.distributed, "is_initialized", lambda: True)
    monkeypatch.setattr(torch.distributed, "destroy_process_group", lambda: calls.append("destroy"))
    distributed.shutdown_process_group()
    assert calls == ["destroy"]


def test_a_failing_rank_other_than_0_leaves_rank_0s_run_folder_alone(tmp_path, monkeypatch):
    """Rank 0 has written config.json (no checkpoint yet) when rank 1 fails: rank 1 removes nothing; a failing
    rank 0 cleans up its own folder, as a single process does."""
    import argparse

    import pytest

    from pchc_rsl.cli import train
    from pchc_rsl.configs import task_config

    def failing(*args, **kwargs):
        raise ValueError("this rank failed")

    monkeypatch.setattr(train, "make_runner", failing)
    monkeypatch.setattr(train, "_stop_on_signals", lambda: None)
    args = argparse.Namespace(threads=None, verbose=False, resume=None, init_from=None)
    for rank, kept in (("1", True), ("0", False)):
        folder = tmp_path / f"run{rank}"
        folder.mkdir()
        (folder / "config.json").write_text("{}")
        monkeypatch.setenv("WORLD_SIZE", "2")
        monkeypatch.setenv("RANK", rank)
        with pytest.raises(SystemExit, match="this rank failed"):
            train.train(task_config("toy"), {}, str(folder), args)
        assert (folder / "config.json").exists() == kept, rank
