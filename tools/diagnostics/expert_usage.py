"""Which experts a mixture actor (PCI or gated) uses at each preference, over the states its own policy visits.

    python tools/diagnostics/expert_usage.py RUN/model_final.pt [--preferences 11] [--steps 200] [--num-envs 8]

Why: an expert trains on the samples in proportion to its routing weight. PCI's routing is fixed by lambda, so
the preferences partition the data among the experts; the gated ablation learns its gate, and this shows whether
it partitions them too or shares experts across preferences. Prints, per preference, each expert's mean weight,
the entropy of those mean weights and the mean entropy state by state (nats; log E when even), then each expert's
share of all the routing weight over the preferences (what it trains on when lambda is sampled evenly).
"""

from __future__ import annotations

import argparse

import numpy as np

from pchc_rsl.evaluation.expert_usage import expert_usage


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("checkpoint")
    parser.add_argument("--preferences", type=int, default=11, help="evenly spaced from (1, 0) to (0, 1)")
    parser.add_argument("--steps", type=int, default=200, help="policy steps per preference")
    parser.add_argument("--num-envs", type=int, default=8)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    try:
        usage = expert_usage(args.checkpoint, args.preferences, args.steps, args.num_envs, args.seed)
    except ValueError as error:
        raise SystemExit(f"expert_usage: {error}") from None
    experts = usage["weights"].shape[1]
    print(f"{args.checkpoint}: mean routing weight of each expert, {args.num_envs} envs x {args.steps} steps each; "
          f"entropy of the mean weights and mean entropy per state (nats, even: {np.log(experts):.3f})")
    print("preference     " + " ".join(f"  e{j}  " for j in range(experts)) + "  entropy  per state")
    for lam, w, e, per_state in zip(*(usage[k] for k in ("preferences", "weights", "entropy", "per_state_entropy"))):
        print(f"({lam[0]:.2f}, {lam[1]:.2f})  " + " ".join(f"{x:6.3f}" for x in w) + f"  {e:7.3f}  {per_state:9.3f}")
    print("share          " + " ".join(f"{x:6.3f}" for x in usage["weights"].mean(0)))
    return usage


if __name__ == "__main__":
    main()
