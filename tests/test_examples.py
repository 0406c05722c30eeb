"""examples/rsl_rl_integration.py, run as a user runs it: MultiCriticPPO and the PCI actor in rsl-rl's own
OnPolicyRunner on an environment written from scratch. One policy must end near goal A = (1, 0) at lambda = (1, 0)
and near goal B = (0, 1) at lambda = (0, 1)."""

import re
import subprocess
import sys
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "rsl_rl_integration.py"


def test_the_rsl_rl_example_reaches_each_goal_at_its_preference(tmp_path):
    onnx = tmp_path / "policy.onnx"
    result = subprocess.run([sys.executable, str(EXAMPLE), "--onnx", str(onnx)], capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    ends = {name: (float(x), float(y)) for name, x, y in
            re.findall(r"lambda = (\(.*?\)): ends at \((-?[\d.]+), (-?[\d.]+)\)", result.stdout)}
    assert set(ends) == {"(1, 0)", "(0.5, 0.5)", "(0, 1)"}, result.stdout[-2000:]
    distance = lambda p, q: ((p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2) ** 0.5  # noqa: E731
    assert distance(ends["(1, 0)"], (1.0, 0.0)) < 0.35, ends
    assert distance(ends["(0, 1)"], (0.0, 1.0)) < 0.35, ends
    # in between, a compromise: nearer the midpoint of the goals than either goal
    assert distance(ends["(0.5, 0.5)"], (0.5, 0.5)) < distance(ends["(0.5, 0.5)"], (1.0, 0.0)), ends
    # the exported file runs with a preference input of its own
    import numpy as np

    from pchc_rsl.export.onnx_policy import OnnxPolicy

    policy = OnnxPolicy(str(onnx))
    actions = policy(np.zeros((3, policy.obs_dim), np.float32), np.array([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]]))
    assert actions.shape == (3, 2)
