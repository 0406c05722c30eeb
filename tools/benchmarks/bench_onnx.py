"""Latency of an exported PCHC policy at batch 1 on one CPU thread (a robot runs it at 50 Hz on its own computer).

Builds a PCI actor of the G1 walking size (current + 5 history frames of 70 values, 20 actions), exports it, and
times onnxruntime against eager torch on the same inputs in the same run. Prints medians; target < 0.2 ms.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time

import numpy as np
import torch
from tensordict import TensorDict

from pchc_rsl.export.onnx_export import export_onnx
from pchc_rsl.export.onnx_policy import OnnxPolicy
from pchc_rsl.modules import GatedMoEActor, PCIActor, PreferenceMLPModel


def median_call_ms(fn, calls: int, repeats: int = 5) -> float:
    """Median over ``repeats`` blocks of the mean time per call of ``fn`` (ms)."""
    for _ in range(100):
        fn()
    blocks = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        blocks.append((time.perf_counter() - start) / calls * 1e3)
    return statistics.median(blocks)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--calls", type=int, default=2000)
    parser.add_argument("--frame", type=int, default=70)
    parser.add_argument("--actions", type=int, default=20)
    args = parser.parse_args()
    torch.set_num_threads(1)
    obs = TensorDict({"policy": torch.randn(1, 6 * args.frame), "preference": torch.tensor([[0.3, 0.7]])}, [1])
    groups = {"actor": ["policy", "preference"]}
    gaussian = {"class_name": "rsl_rl.modules:GaussianDistribution", "init_std": 1.0}
    print(f"{'actor':<20}{'onnxruntime ms':>16}{'torch ms':>12}{'torch/ort':>11}")
    for cls in (PCIActor, GatedMoEActor, PreferenceMLPModel):
        actor = cls(obs, groups, "actor", args.actions, hidden_dims=[256, 128], obs_normalization=True,
                    distribution_cfg=gaussian).eval()
        with tempfile.TemporaryDirectory() as tmp:
            policy = OnnxPolicy(export_onnx(actor, f"{tmp}/policy.onnx"), num_threads=1)
            o, lam = obs["policy"].numpy(), obs["preference"].numpy()
            session, feeds = policy.session, {"obs": o, "preference": lam}
            ort_ms = median_call_ms(lambda: session.run(["actions"], feeds), args.calls)
            with torch.inference_mode():
                torch_ms = median_call_ms(lambda: actor(obs), args.calls)
            np.testing.assert_allclose(policy(o, lam), actor(obs).detach().numpy(), atol=1e-5)
        print(f"{cls.__name__:<20}{ort_ms:>16.4f}{torch_ms:>12.4f}{torch_ms / ort_ms:>11.2f}")


if __name__ == "__main__":
    main()
