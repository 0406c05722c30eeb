"""tools/mo_study.py: workers sharing one study each take a different cell (a stopped worker's cell is rerun), and
the routing table's expert shares."""

import os
import subprocess
import sys

import numpy as np
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


def test_expert_training_shares_match_an_integral_of_the_beta_density():
    """Reference: integrate the normalised Beta densities at the (clamped) positions over lambda_1 ~ Beta(c, c)."""
    from scipy import integrate
    from scipy.stats import beta

    positions = np.clip([0.0, 0.25, 0.5, 0.75, 1.0], 0.01, 0.99)

    def weight(lam_1, j, scale):
        densities = beta.pdf(positions, 1 + scale * lam_1, 1 + scale * (1 - lam_1))
        return densities[j] / densities.sum()

    for scale, concentration in [(10.0, 1.0), (3.0, 1.0), (10.0, 0.5)]:
        expected = [integrate.quad(lambda x: weight(x, j, scale) * beta.pdf(x, concentration, concentration), 0, 1,
                                   limit=200)[0] for j in range(5)]
        np.testing.assert_allclose(mo_study.expert_training_shares(scale, concentration), expected, atol=2e-3)
