"""The PCI experts' forward and backward pass: one batched product per layer against one product per expert.

    python tools/benchmarks/bench_experts.py [--batch 6144] [--hidden 128 64] [--repeats 15] [--threads 1]

Both evaluate the same stacked weights ([E, in, out] per layer) on one mini-batch (6144 = a G1 mini-batch at 1024
envs) and must agree; the two are timed interleaved, and the medians and their ratio are printed. BatchedExperts
uses the per-expert form because it is the faster one here.
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from pchc_rsl.modules.pci import BatchedExperts


def batched(module: BatchedExperts, x: torch.Tensor) -> torch.Tensor:
    """The batched form: einsum for the shared input, then baddbmm per layer."""
    h = torch.einsum("ni,eio->eno", x, module.weights[0]) + module.biases[0]
    for weight, bias in zip(module.weights[1:], module.biases[1:]):
        h = torch.baddbmm(bias, module.activation(h), weight)
    return h


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--batch", type=int, default=6144)
    parser.add_argument("--input", type=int, default=104, help="current frame + lambda + history latent (G1 walk)")
    parser.add_argument("--hidden", type=int, nargs="+", default=[128, 64])
    parser.add_argument("--experts", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    module = BatchedExperts(args.experts, args.input, 20, args.hidden, "elu")
    x = torch.randn(args.batch, args.input)
    torch.testing.assert_close(module(x), batched(module, x), rtol=1e-5, atol=1e-5)

    def train_step(forward) -> float:
        module.zero_grad()
        start = time.perf_counter()
        forward(x).square().mean().backward()
        return time.perf_counter() - start

    times = {"batched": [], "per expert": []}
    for _ in range(args.repeats):
        times["batched"].append(train_step(lambda v: batched(module, v)))
        times["per expert"].append(train_step(module))
    medians = {name: statistics.median(values) for name, values in times.items()}
    print(f"{args.experts} experts {args.input}->{args.hidden}->20, batch {args.batch}, {args.threads} thread(s); "
          f"forward + backward, median of {args.repeats}")
    for name, value in medians.items():
        print(f"  {name:<11} {1000 * value:7.1f} ms")
    print(f"  per expert / batched: {medians['per expert'] / medians['batched']:.2f}")


if __name__ == "__main__":
    main()
