"""What the reward pays a walker for, term by term: each reward term's mean pay per second (weight x value) over the
envs and a stretch of steady walking at one constant command, pushes off, per preference, with each group's sum.

    python tools/diagnostics/reward_terms.py CKPT [--preference 0.25,0.75 --preference 0,1] [--command 0.5 0 0]
                                             [--num-envs 64]
                                 [--sampled-actions]

Why: to tell a reward that pays for a behaviour from a policy that falls short of what its reward pays. Every
preference's gait is scored by the same terms, so when, at the same command, the gait at one preference earns less of
every group that preference weights than the gait at another, the policy there falls short of its own reward. The
terms are read after each step, on the state the env's reward was computed on, except in an env that fell in that
step, which is read after its reset.

``--sampled-actions`` scores the gait that training sees, the policy's action noise included, instead of its mean
(what the robot runs): where the two differ much, the policy is trained on a gait other than the one it deploys.
"""

from __future__ import annotations

import argparse

import torch

SETTLE_S, MEASURE_S = 1.0, 9.0


def term_name(term) -> str:
    """'track_lin_vel_xy (std 0.5)' from the term's function and params."""
    name = term.func.split(":")[-1].split(".")[-1]
    params = ", ".join(f"{key} {value}" for key, value in term.params.items() if isinstance(value, (int, float)))
    return f"{name} ({params})" if params else name


def mean_term_pay(env, policy, preference, command, settle_s: float = SETTLE_S,
                  measure_s: float = MEASURE_S) -> torch.Tensor:
    """[terms] each term's weight x value averaged over the envs and measure_s after settle_s, per second (the
    env's reward groups add these times dt each step)."""
    from pchc_rsl.evaluation import steady_walk

    pay, measured = torch.zeros(len(env.rewards.terms)), 0
    for _, measuring in steady_walk(env, policy, preference, command, settle_s, measure_s):
        if measuring:
            pay += env.rewards.term_pay(env).mean(dim=0).cpu()
            measured += 1
    return pay / measured


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoint")
    parser.add_argument("--preference", action="append", help="lambda as a,b (repeatable; default (1, 0) to (0, 1))")
    parser.add_argument("--command", type=float, nargs=3, default=[0.5, 0.0, 0.0], metavar=("VX", "VY", "WZ"))
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--sampled-actions", action="store_true",
                        help="act with the policy's action noise, as in training (default: its mean, as deployed)")
    args = parser.parse_args()

    from pchc_rsl.evaluation import evenly_spaced_preferences
    from pchc_rsl.evaluation.checkpoint import load_policy

    _, env, policy = load_policy(args.checkpoint, args.num_envs, args.seed, SETTLE_S + MEASURE_S + 1.0, None,
                                 ["env.push.enabled=false"])
    preferences = ([tuple(float(x) for x in p.split(",")) for p in args.preference] if args.preference
                   else evenly_spaced_preferences(5))
    act = (lambda obs: policy(obs, stochastic_output=True)) if args.sampled_actions else policy
    pays = [mean_term_pay(env, act, p, args.command) for p in preferences]
    terms = [term for _, term in env.rewards.terms]
    print(f"{args.checkpoint}: pay per second (weight x value), {args.num_envs} envs, told {tuple(args.command)}, "
          f"pushes off, over {MEASURE_S:g} s after {SETTLE_S:g} s, "
          f"{'sampled actions (training noise)' if args.sampled_actions else 'mean actions'}")
    print("| term | group | " + " | ".join(f"({', '.join(f'{x:g}' for x in p)})" for p in preferences) + " |")
    print("|---|---|" + "---|" * len(preferences))
    for i, term in enumerate(terms):
        print(f"| {term_name(term)} | {term.group} | " + " | ".join(f"{pay[i]:.4f}" for pay in pays) + " |")
    for group in env.rewards.names:
        members = [i for i, term in enumerate(terms) if term.group == group]
        print(f"| **{group}, sum** | {group} | " + " | ".join(f"{pay[members].sum():.4f}" for pay in pays) + " |")


if __name__ == "__main__":
    main()
