"""Fall recovery's energy split by phase, with the pushes off and with pchc-eval's mild pushes.

    python tools/diagnostics/fall_energy_by_phase.py policies/g1_fall_recovery.pt --num-envs 128

Why: Table I's energy mixes getting up (hundreds of J/s) with standing (tens of J/s) and the push responses in
it. Turning the pushes off shows whether a preference's standing energy comes from reacting to pushes or from how
it stands. Same evaluation preset as pchc-eval (no randomisation, no noise, no curriculum), seed 0.
"""

from __future__ import annotations

import argparse

from pchc_rsl.evaluation import evaluation_config, loaded_policy, task_config_of
from pchc_rsl.evaluation import aggregate, evenly_spaced_preferences, format_metric, run_episodes


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("checkpoint")
    parser.add_argument("--num-envs", type=int, default=128, help="episodes per preference and push setting")
    parser.add_argument("--preferences", type=int, default=5)
    args = parser.parse_args(argv)
    config = task_config_of(args.checkpoint, "g1-fall-recovery", "fall_energy_by_phase", "fall recovery")
    rows = []
    print("pushes  preference    energy getting up (J/s)  energy standing (J/s)  success (%)")
    for pushes in ("off", "mild"):
        cfg = evaluation_config(config, "mild", args.num_envs, seed=0)
        cfg.env.push.enabled = pushes == "mild"
        runner, policy = loaded_policy(args.checkpoint, cfg)
        for lam in evenly_spaced_preferences(args.preferences):
            s = aggregate(run_episodes(runner.env, policy, lam, 1)[0])
            rows.append({"pushes": pushes, "preference": lam, **s})
            up, stand = (f"{format_metric(s[k], s[f'{k}_ci95'], k, digits=1):>16s}"
                         for k in ("energy_recovery", "energy_standing"))
            print(f"{pushes:6s}  ({lam[0]:.2f}, {lam[1]:.2f})  {up}      {stand}    {s['success']:6.1f}", flush=True)
    return rows


if __name__ == "__main__":
    main()
