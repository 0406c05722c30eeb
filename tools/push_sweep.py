"""Fall recovery: success under pchc-eval's strong-push preset at several push speeds, per preference.

    python tools/push_sweep.py policies/g1_fall_recovery.pt --speeds 1.2 1.6 2.0 --num-envs 64

Why: Table I's success under strong pushes can only order the preferences if the push is strong enough to topple
some of them. The paper does not give its push strength (its COM displacements under mild pushes, 0.75-1.82 m, say
its pushes are far stronger than ours), so this shows where along the push speed each preference starts to fall.
Everything but the speed is pchc-eval's strong preset (a push every 3 s once standing, no randomisation, seed 0).
Prints a markdown table: success (%) with its Wilson 95% interval, one column per speed.
"""

from __future__ import annotations

import argparse

from pchc_rsl.evaluation import evaluation_config, loaded_policy, task_config_of
from pchc_rsl.evaluation import aggregate, evenly_spaced_preferences, run_episodes


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("checkpoint")
    parser.add_argument("--speeds", type=float, nargs="+", default=[1.2, 1.6, 2.0], help="push speeds, m/s")
    parser.add_argument("--num-envs", type=int, default=64, help="episodes per preference and speed")
    parser.add_argument("--preferences", type=int, default=5)
    args = parser.parse_args(argv)
    config = task_config_of(args.checkpoint, "g1-fall-recovery", "push_sweep", "fall recovery")
    preferences = evenly_spaced_preferences(args.preferences)
    success: dict = {lam: {} for lam in preferences}
    for speed in args.speeds:
        cfg = evaluation_config(config, "strong", args.num_envs, seed=0)
        cfg.env.push.velocity = (speed, speed)
        runner, policy = loaded_policy(args.checkpoint, cfg)
        for lam in preferences:
            summary = aggregate(run_episodes(runner.env, policy, lam, 1)[0])
            success[lam][speed] = (summary["success"], summary["success_ci95"])
    print(f"Success (%) under a push every 3 s at each speed, {args.num_envs} episodes per cell ({args.checkpoint})")
    print()
    print("| Preference | " + " | ".join(f"{s:g} m/s" for s in args.speeds) + " |")
    print("|---|" + "---|" * len(args.speeds))
    for lam, row in success.items():
        cells = (f"{rate:.1f} [{low:.1f}, {high:.1f}]" for rate, (low, high) in row.values())
        print(f"| ({lam[0]:.2f}, {lam[1]:.2f}) | " + " | ".join(cells) + " |")
    return success


if __name__ == "__main__":
    main()
