"""tools/mo_study.py: workers sharing one study each take a different cell, and a stopped worker's cell is rerun."""

import os
import subprocess
import sys

from tool_loader import load_tool

mo_study = load_tool("mo_study")


def dead_pid() -> int:
    process = subprocess.Popen([sys.executable, "-c", "pass"])
    process.wait()
    return process.pid


def test_a_free_cell_is_claimed_once(tmp_path):
    folder = str(tmp_path / "task" / "pci_seed1")
    assert mo_study.claim_cell(folder)
    assert (tmp_path / "task" / "pci_seed1").is_dir()
    assert (tmp_path / "task" / "pci_seed1.claim").read_text() == str(os.getpid())
    assert not mo_study.claim_cell(folder)  # held by a live process (this one)
    assert sorted(p.name for p in (tmp_path / "task").iterdir()) == ["pci_seed1", "pci_seed1.claim"]


def test_a_live_workers_cell_is_skipped(tmp_path):
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (tmp_path / "task").mkdir()
        (tmp_path / "task" / "pci_seed1").mkdir()
        (tmp_path / "task" / "pci_seed1" / "log.txt").write_text("half-way")
        (tmp_path / "task" / "pci_seed1.claim").write_text(str(sleeper.pid))
        assert not mo_study.claim_cell(str(tmp_path / "task" / "pci_seed1"))
        assert (tmp_path / "task" / "pci_seed1" / "log.txt").read_text() == "half-way"
    finally:
        sleeper.kill()


def test_a_stopped_workers_cell_is_cleared_and_taken(tmp_path):
    (tmp_path / "task").mkdir()
    (tmp_path / "task" / "pci_seed1").mkdir()
    (tmp_path / "task" / "pci_seed1" / "log.txt").write_text("half-way")
    (tmp_path / "task" / "pci_seed1.claim").write_text(str(dead_pid()))
    assert mo_study.claim_cell(str(tmp_path / "task" / "pci_seed1"))
    assert list((tmp_path / "task" / "pci_seed1").iterdir()) == []


def test_a_finished_cell_is_not_claimed(tmp_path):
    (tmp_path / "task" / "pci_seed1").mkdir(parents=True)
    (tmp_path / "task" / "pci_seed1" / "result.json").write_text("{}")
    assert not mo_study.claim_cell(str(tmp_path / "task" / "pci_seed1"))
    assert not (tmp_path / "task" / "pci_seed1.claim").exists()
