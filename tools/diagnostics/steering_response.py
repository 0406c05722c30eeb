"""How a walker answers the steering commands, per preference, pushes off: the yaw rate it turns at when told
+-0.5 rad/s (walking 0.5 m/s), the forward speed told 0.5 m/s straight, and how far its heading strays walking
straight.

    python tools/diagnostics/steering_response.py CKPT [CKPT ...] [--num-envs 32] [--preferences 3]
                                                  [--yaw-rates 0.25 0.5 1]
                                      [--sampled-actions]

Why: a quick side-by-side of checkpoints (a reward change against the same budget without it) on the figures a
robot's operator feels, measured after the walker got going (the first second is left out) over 7 s, so that the
start-up does not count as error. pchc-eval's robustness conditions give the same quantities over whole episodes,
with pushes, and with intervals.

``--sampled-actions`` acts as in training, with the policy's action noise, instead of its mean (what the robot
runs): a walker that keeps the commanded speed only under noise learned to offset that noise, not to track.
"""

from __future__ import annotations

import argparse
import math

import torch

from pchc_rsl.envs.g1.commands import wrap_angle
from pchc_rsl.evaluation import evenly_spaced_preferences, steady_walk

SETTLE_S, MEASURE_S = 1.0, 7.0


def response(env, policy, preference, command, sampled: bool = False) -> dict:
    """Per env over MEASURE_S after SETTLE_S at a constant command: mean yaw rate (rad/s), mean forward speed (m/s,
    base frame), heading change (deg). ``sampled``: actions drawn from the policy's distribution, not its mean."""
    act = (lambda obs: policy(obs, stochastic_output=True)) if sampled else policy
    turned = torch.zeros(env.num_envs)
    speed = torch.zeros(env.num_envs)
    measured = 0
    for _, measuring in steady_walk(env, act, preference, command, SETTLE_S, MEASURE_S):
        yaw = env.robot.yaw.clone()
        if measuring:
            turned += wrap_angle(yaw - previous)
            speed += env.robot.base_lin_vel[:, 0]
            measured += 1
        previous = yaw
    return {"yaw_rate": turned / (measured * env.dt), "speed": speed / measured,
            "heading_change": turned.abs() * 180.0 / math.pi}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoints", nargs="+")
    parser.add_argument("--num-envs", type=int, default=32)
    parser.add_argument("--preferences", type=int, default=3, help="evenly spaced from (1, 0) to (0, 1)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--yaw-rates", type=float, nargs="+", default=[0.5],
                        help="left turns to measure (rad/s, at 0.5 m/s); the right turn is told -0.5")
    parser.add_argument("--sampled-actions", action="store_true",
                        help="act with the policy's action noise, as in training (default: its mean, as deployed)")
    args = parser.parse_args()
    tests = [(f"+{w:g}", (0.5, 0.0, w)) for w in args.yaw_rates] + [("-0.5", (0.5, 0.0, -0.5)),
                                                                      ("straight", (0.5, 0.0, 0.0))]

    from pchc_rsl.evaluation.checkpoint import load_policy

    print(f"{args.num_envs} envs per cell, pushes off, measured {MEASURE_S:g} s after {SETTLE_S:g} s; medians over "
          "envs of the yaw rate told +-0.5 rad/s at 0.5 m/s, the speed told 0.5 m/s straight, |heading change|; "
          + ("actions sampled with the training noise" if args.sampled_actions else "the policy's mean actions"))
    turns = [name for name, _ in tests[:-1]]
    print("| checkpoint | lambda | " + " | ".join(f"yaw rate told {name}" for name in turns)
          + " | speed told 0.5 | heading change, median | p90 |")
    print("|---|---|" + "---|" * (len(turns) + 3))
    for path in args.checkpoints:
        _, env, policy = load_policy(path, args.num_envs, args.seed, SETTLE_S + MEASURE_S + 1.0, None,
                                     ["env.push.enabled=false"])
        for preference in evenly_spaced_preferences(args.preferences):
            r = {name: response(env, policy, preference, command, args.sampled_actions) for name, command in tests}
            shown = ", ".join(f"{x:g}" for x in preference)
            straight = r["straight"]["heading_change"]
            print(f"| {path} | ({shown}) | " + " | ".join(f"{r[name]['yaw_rate'].median():.3f}" for name in turns)
                  + f" | {r['straight']['speed'].median():.3f} | {straight.median():.1f} | {straight.quantile(0.9):.1f} |",
                  flush=True)


if __name__ == "__main__":
    main()
