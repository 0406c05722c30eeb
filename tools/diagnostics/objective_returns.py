"""Each reward group's undiscounted episode return at each preference, under pchc-eval's evaluation preset.

    python tools/diagnostics/objective_returns.py policies/g1_fall_recovery.pt --pushes mild --num-envs 64

Why: the paper's table measures physical quantities (energy in J/s, COM displacement) that the rewards only stand
in for. The returns of the reward groups are what MultiCriticPPO optimises, so they tell whether a preference's
policy does best on the objective it weights (the energy return should be highest at (1, 0), and so on), apart from
how well the reward matches the metric. Returns are the per-step rewards the critics learn from, summed over each
env's first episode. G1 tasks; --pushes off turns the evaluation preset's pushes off, any other preset of the task
(e.g. force-mild) pushes with it. --by-outcome splits the episodes into those that fell and those that stayed up: where
a group's return is higher in the episodes that fell, a fall is that objective's cheapest answer to the pushes.
"""

from __future__ import annotations

import argparse

from pchc_rsl.evaluation import aggregate, evenly_spaced_preferences, format_metric
from pchc_rsl.evaluation.group_returns import first_episode_returns, policy_under_pushes


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("checkpoint")
    parser.add_argument("--pushes", default="mild", help="off, or one of the task's push presets (default mild)")
    parser.add_argument("--num-envs", type=int, default=64, help="episodes per preference")
    parser.add_argument("--preferences", type=int, default=5)
    parser.add_argument("--by-outcome", action="store_true", help="the returns of fallen and of standing episodes")
    args = parser.parse_args(argv)
    cfg, runner, policy = policy_under_pushes(args.checkpoint, args.pushes, args.num_envs, "objective_returns")
    names = ["task", *cfg.env.objective_names]
    print(f"Undiscounted episode return of each reward group, pushes {args.pushes}, {args.num_envs} episodes per "
          f"preference ({args.checkpoint}); mean ± 95% interval half-width")
    print()
    outcomes = {"fell": True, "stayed up": False} if args.by_outcome else {"all": None}
    print("| Preference | " + ("episodes | " if args.by_outcome else "") + " | ".join(names) + " |")
    print("|---|" + "---|" * (len(names) + bool(args.by_outcome)))
    table = {}
    for lam in evenly_spaced_preferences(args.preferences):
        returns, fell, _ = first_episode_returns(runner.env, policy, lam)
        for outcome, fallen in outcomes.items():
            rows = returns if fallen is None else returns[fell == fallen]
            summary = aggregate([dict(zip(names, row.tolist())) for row in rows]) if len(rows) else {}
            table[(lam, outcome)] = summary
            cells = (format_metric(summary[n], summary[f"{n}_ci95"], n, digits=3) if summary else "-" for n in names)
            label = f"{outcome} ({len(rows)}) | " if fallen is not None else ""
            print(f"| ({lam[0]:.2f}, {lam[1]:.2f}) | {label}" + " | ".join(cells) + " |", flush=True)
    return table


if __name__ == "__main__":
    main()
