"""How a checkpoint's AMP discriminator scores the reference clips and the policy's own gait: the mean score D and
style reward per step over the clips' windows, and over the windows the policy walks at each preference.

    python tools/diagnostics/style_score.py CKPT [--motion-files PATH ...] [--preferences 3] [--num-envs 32]
                                            [--command 0.5 0 0]

Why: the style reward c max(0, 1 - (D - 1)^2 / 4) is 0 wherever D <= -1, so a discriminator that tells every policy
window from the clips' pays no style at all, and the gait is shaped by the other terms alone. Training logs D's means
on its replay buffer (`Critic/amp/d_ref`, `Critic/amp/d_policy`); this reads D on the gait the robot would run (the
policy's mean actions, pushes off, told one constant command), per preference.
"""

from __future__ import annotations

import argparse

import torch

SETTLE_S, MEASURE_S = 1.0, 4.0


def style_of(style, windows: torch.Tensor) -> tuple[float, float]:
    """(mean D, mean style reward per step) of windows [N, window * joints] under an AMPStyle's discriminator."""
    with torch.inference_mode():
        score = style.discriminator(windows)
        return float(score.mean()), float(style.discriminator.style_reward(windows, style.scale).mean())


def walked_windows(env, policy, preference, command, group: str) -> torch.Tensor:
    """[steps * N, window * joints] the AMP windows (observation ``group``) of MEASURE_S of walking after SETTLE_S
    at ``command``."""
    from pchc_rsl.evaluation import steady_walk

    walked = steady_walk(env, policy, preference, command, SETTLE_S, MEASURE_S)
    return torch.cat([obs[group].clone() for obs, measuring in walked if measuring])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoint")
    parser.add_argument("--motion-files", nargs="+", help="the reference clips (default: those the checkpoint names)")
    parser.add_argument("--preferences", type=int, default=3, help="evenly spaced from (1, 0) to (0, 1)")
    parser.add_argument("--num-envs", type=int, default=32)
    parser.add_argument("--command", type=float, nargs=3, default=[0.5, 0.0, 0.0], metavar=("VX", "VY", "WZ"))
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    from pchc_rsl.algorithms import MultiCriticPPO
    from pchc_rsl.amp.style import AMPStyle
    from pchc_rsl.evaluation import evenly_spaced_preferences
    from pchc_rsl.evaluation.checkpoint import load_policy
    from pchc_rsl.runners import load_checkpoint

    saved = load_checkpoint(args.checkpoint)
    amp_cfg = dict((saved.get("config") or {}).get("runner", {}).get("algorithm", {}).get("amp_cfg") or {})
    if "amp_state_dict" not in saved or not amp_cfg:
        raise SystemExit(f"style_score: {args.checkpoint} was trained without AMP; it has no discriminator.")
    if args.motion_files:
        amp_cfg["motion_files"] = args.motion_files
    _, env, policy = load_policy(args.checkpoint, args.num_envs, args.seed, SETTLE_S + MEASURE_S + 1.0, None,
                                 ["env.push.enabled=false"])
    style = AMPStyle(**MultiCriticPPO.resolve_amp_config(amp_cfg, env.get_observations(), env))
    style.load_state_dict(saved["amp_state_dict"])

    print(f"{args.checkpoint}: discriminator score D (clips +1, policy -1 when told apart) and style reward per step "
          f"(at most {style.scale:g}); policy windows over {MEASURE_S:g} s after {SETTLE_S:g} s, {args.num_envs} envs, "
          f"told {tuple(args.command)}, pushes off")
    print("| windows | D | style reward |")
    print("|---|---|---|")
    score, reward = style_of(style, style.reference.sample(4096))
    print(f"| reference clips | {score:.3f} | {reward:.4f} |")
    for preference in evenly_spaced_preferences(args.preferences):
        score, reward = style_of(style, walked_windows(env, policy, preference, args.command, style.obs_group))
        print(f"| policy at ({', '.join(f'{x:g}' for x in preference)}) | {score:.3f} | {reward:.4f} |", flush=True)


if __name__ == "__main__":
    main()
