"""tools/diagnostics/expert_usage.py: the routing weights it reports, against the Beta density computed with scipy."""

import numpy as np
import pytest
from scipy.stats import beta
from tool_loader import load_tool

from pchc_rsl.cli import train as train_cli
from pchc_rsl.preference import DEFAULT_ROUTING_SCALE

expert_usage = load_tool("diagnostics/expert_usage")


def toy_run(tmp_path, *extra):
    train_cli.main(["--task", "toy", "--num-envs", "4", "--max-iterations", "1", "--log-dir", str(tmp_path), *extra])
    return str(tmp_path / "model_0.pt")


def test_pci_weights_are_the_normalised_beta_density_at_the_expert_positions(tmp_path, capsys):
    weights = expert_usage.main([toy_run(tmp_path), "--preferences", "3", "--steps", "3", "--num-envs", "2"])["weights"]
    positions = np.clip([0.0, 0.25, 0.5, 0.75, 1.0], 0.01, 0.99)  # the routing rule's clamp, eps = 0.01
    for row, lam_1 in zip(weights, [1.0, 0.5, 0.0]):
        s = DEFAULT_ROUTING_SCALE  # alpha0 = beta0 = 1
        density = beta.pdf(positions, 1 + s * lam_1, 1 + s * (1 - lam_1))
        np.testing.assert_allclose(row, density / density.sum(), atol=1e-5)
    assert "share" in capsys.readouterr().out


def test_an_actor_without_experts_is_refused(tmp_path):
    with pytest.raises(SystemExit, match="not a mixture of experts"):
        expert_usage.main([toy_run(tmp_path, "--actor", "mlp"), "--preferences", "2", "--steps", "1"])
