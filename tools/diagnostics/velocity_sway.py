"""How much a walker's base velocity sways within its steps, against the averaged velocity the task's tracking terms
read (``env.command.velocity_average``), per preference, walking straight at 0.5 m/s, pushes off.

    python tools/diagnostics/velocity_sway.py policies/g1_walk.pt --num-envs 8

Why: a speed gate narrower than the sway charges the gait's own oscillation (mostly sideways, the pelvis moving
over each stance foot) rather than a bias of the mean speed; this prints both, per axis, so a gate's width can be
set against them. Medians over envs of the standard deviation over time, measured over 4 s after 2 s of walking.
"""

from __future__ import annotations

import argparse

import torch

from pchc_rsl.evaluation import evenly_spaced_preferences

SETTLE_S, MEASURE_S = 2.0, 4.0


def sway(env, policy, preference) -> dict:
    """Per env: mean forward speed, and the std over time of the instantaneous and averaged base-frame velocity."""
    settle, steps = round(SETTLE_S / env.dt), round((SETTLE_S + MEASURE_S) / env.dt)
    instantaneous, averaged = [], []
    with torch.inference_mode():
        env.set_preference(preference)
        env.reset()
        obs = env.get_observations()
        for k in range(steps):
            env.commands[:] = torch.tensor([0.5, 0.0, 0.0])
            obs, _, _, _ = env.step(policy(obs))
            if k >= settle:
                instantaneous.append(env.robot.base_lin_vel[:, :2].clone())
                averaged.append(env.command.velocity_average[:, :2].clone())
    instantaneous, averaged = torch.stack(instantaneous), torch.stack(averaged)
    return {"speed": instantaneous[..., 0].mean(0), "instantaneous": instantaneous.std(0),
            "averaged": averaged.std(0)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoint")
    parser.add_argument("--num-envs", type=int, default=8)
    parser.add_argument("--preferences", type=int, default=3, help="evenly spaced from (1, 0) to (0, 1)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    from pchc_rsl.evaluation.checkpoint import load_policy

    _, env, policy = load_policy(args.checkpoint, args.num_envs, args.seed, SETTLE_S + MEASURE_S + 1.0, None,
                                 ["env.push.enabled=false"])
    print(f"{args.num_envs} envs, told 0.5 m/s straight, pushes off; std over {MEASURE_S:g} s after {SETTLE_S:g} s "
          "(m/s), median over envs")
    print("| lambda | forward speed | forward sway | sideways sway | forward sway, averaged "
          "| sideways sway, averaged |")
    print("|---|---|---|---|---|---|")
    for preference in evenly_spaced_preferences(args.preferences):
        r = sway(env, policy, preference)
        inst, avg = r["instantaneous"].median(0).values, r["averaged"].median(0).values
        shown = ", ".join(f"{x:g}" for x in preference)
        print(f"| ({shown}) | {r['speed'].median():.3f} | {inst[0]:.3f} | {inst[1]:.3f} | {avg[0]:.3f} "
              f"| {avg[1]:.3f} |", flush=True)


if __name__ == "__main__":
    main()
