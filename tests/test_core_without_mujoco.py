import subprocess
import sys

BLOCK_MUJOCO = """
import sys
class Block:
    def find_spec(self, name, path=None, target=None):
        if name == "mujoco" or name.startswith("mujoco.") or name.startswith("mujoco_menagerie"):
            raise ImportError("mujoco is blocked for this test")
sys.meta_path.insert(0, Block())
import pchc_rsl, pchc_rsl.modules, pchc_rsl.algorithms, pchc_rsl.storage, pchc_rsl.runners
import pchc_rsl.preference, pchc_rsl.pareto, pchc_rsl.export.onnx_export, pchc_rsl.export.onnx_policy
from pchc_rsl.modules import PCIActor
from pchc_rsl.algorithms import MultiCriticPPO
assert not any(m == "mujoco" or m.startswith("mujoco") for m in sys.modules), [m for m in sys.modules if "mujoco" in m]
print("ok")
"""


def test_core_imports_with_mujoco_blocked():
    result = subprocess.run([sys.executable, "-c", BLOCK_MUJOCO], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().endswith("ok")
