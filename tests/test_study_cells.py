"""The cells of a benchmark study: workers sharing one study each take a different cell (a stopped worker's cell is
rerun), and a run folder's checkpoints across its resumed training folders."""

import os
import subprocess
import sys

from pchc_rsl.training.study_cells import claim_cell, run_checkpoints, train_folders


def dead_pid() -> int:
    process = subprocess.Popen([sys.executable, "-c", "pass"])
    process.wait()
    return process.pid


def test_a_free_cell_is_claimed_once(tmp_path):
    folder = str(tmp_path / "task" / "pci_seed1")
    assert claim_cell(folder)
    assert (tmp_path / "task" / "pci_seed1").is_dir()
    assert (tmp_path / "task" / "pci_seed1.claim").read_text() == str(os.getpid())
    assert not claim_cell(folder)  # held by a live process (this one)
    assert sorted(p.name for p in (tmp_path / "task").iterdir()) == ["pci_seed1", "pci_seed1.claim"]


def test_a_live_workers_cell_is_skipped(tmp_path):
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (tmp_path / "task").mkdir()
        (tmp_path / "task" / "pci_seed1").mkdir()
        (tmp_path / "task" / "pci_seed1" / "log.txt").write_text("half-way")
        (tmp_path / "task" / "pci_seed1.claim").write_text(str(sleeper.pid))
        assert not claim_cell(str(tmp_path / "task" / "pci_seed1"))
        assert (tmp_path / "task" / "pci_seed1" / "log.txt").read_text() == "half-way"
    finally:
        sleeper.kill()


def test_a_stopped_workers_cell_is_cleared_and_taken(tmp_path):
    (tmp_path / "task").mkdir()
    (tmp_path / "task" / "pci_seed1").mkdir()
    (tmp_path / "task" / "pci_seed1" / "log.txt").write_text("half-way")
    (tmp_path / "task" / "pci_seed1.claim").write_text(str(dead_pid()))
    assert claim_cell(str(tmp_path / "task" / "pci_seed1"))
    assert list((tmp_path / "task" / "pci_seed1").iterdir()) == []


def test_a_finished_cell_is_not_claimed(tmp_path):
    (tmp_path / "task" / "pci_seed1").mkdir(parents=True)
    (tmp_path / "task" / "pci_seed1" / "result.json").write_text("{}")
    assert not claim_cell(str(tmp_path / "task" / "pci_seed1"))
    assert not (tmp_path / "task" / "pci_seed1.claim").exists()


def test_the_newest_checkpoint_of_each_iteration_across_resumed_training_folders(tmp_path):
    for folder, names in (("train", ["model_1.pt", "model_2.pt", "model_final.pt"]), ("train_resumed2", ["model_3.pt"]),
                          ("train_resumed10", ["model_2.pt", "model_4.pt"]), ("train_resumed1", ["model_2.pt"])):
        (tmp_path / folder).mkdir()
        for name in names:
            (tmp_path / folder / name).write_bytes(b"")
    (tmp_path / "train_old").mkdir()
    assert train_folders(str(tmp_path)) == [str(tmp_path / name) for name in
                                            ("train", "train_resumed1", "train_resumed2", "train_resumed10")]
    assert run_checkpoints(str(tmp_path)) == {1: str(tmp_path / "train" / "model_1.pt"),
                                              2: str(tmp_path / "train_resumed10" / "model_2.pt"),
                                              3: str(tmp_path / "train_resumed2" / "model_3.pt"),
                                              4: str(tmp_path / "train_resumed10" / "model_4.pt")}
    assert run_checkpoints(str(tmp_path / "missing")) == {}
