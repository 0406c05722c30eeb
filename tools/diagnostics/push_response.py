"""How a G1 policy answers a push, per preference: in the window after each push (the preset's: 3 s for fall
recovery, until the next push; 1 s for walking), foot touchdowns per second, the median step length, and the
whole-body COM's largest displacement, under the task's mild evaluation preset.

    python tools/diagnostics/push_response.py policies/g1_fall_recovery.pt --num-envs 64
    python tools/diagnostics/push_response.py policies/g1_walk.pt env.push.velocity=1.5,1.5

Why: Table I's COM displacement says how far a push carried the robot, not how the policy answered it. A robot
stops a push by stepping where its momentum goes (a few long catching steps) or by many quick ones; this tells
them apart, and so says whether a preference that drifts further steps more or less than one that drifts less.
"""

from __future__ import annotations

import argparse

import torch

from pchc_rsl.evaluation import evenly_spaced_preferences


def push_response(env, policy, preference) -> dict[str, float]:
    """Roll one episode per env at ``preference``; sums over every step inside a push window (COM displacement:
    windows that ran to their end, not those cut by the episode's end, a fall or the time-out)."""
    touchdowns, window_steps, displacements, steps = 0.0, 0.0, [], []
    with torch.inference_mode():
        env.set_preference(preference)
        env.reset()
        obs = env.get_observations()
        for _ in range(env.max_episode_length):
            was_active = env.pushes.active.clone()
            obs, _, dones, _ = env.step(policy(obs))
            inside = was_active & env.pushes.active
            touchdowns += (env.feet.first_contact.sum(-1) * inside).sum().item()
            window_steps += inside.sum().item()
            touched = env.feet.first_contact & inside.unsqueeze(-1)
            steps += env.feet.stride[touched].tolist()
            closed = was_active & ~env.pushes.active & ~dones.bool()  # a reset clears the maximum
            displacements += env.pushes.max_com_deviation[closed].tolist()
    return {
        "windows": len(displacements),
        "touchdowns_per_s": touchdowns / max(window_steps, 1.0) / env.dt,
        "median_step": float(torch.tensor(steps).median()) if steps else float("nan"),
        "com_displacement": sum(displacements) / max(len(displacements), 1),
    }


def pushes_in_words(push) -> str:
    """The pushes of a PushConfig as a header says them: kicks, forces or both, with their ranges."""
    kinds = []
    if push.velocity_share > 0:
        kinds.append(f"kicks of {push.velocity[0]:g}-{push.velocity[1]:g} m/s")
    force = push.force
    if force.share > 0:
        kinds.append(f"forces of {force.magnitude[0]:g}-{force.magnitude[1]:g} N for {force.duration_s[0]:g}-"
                     f"{force.duration_s[1]:g} s on {', '.join(force.bodies)}")
    return " and ".join(kinds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoint")
    parser.add_argument("overrides", nargs="*", help="config overrides after the evaluation preset (KEY=VALUE)")
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--preferences", type=int, default=3, help="evenly spaced from (1, 0) to (0, 1)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    from pchc_rsl.evaluation import load_policy

    _, env, policy = load_policy(args.checkpoint, args.num_envs, args.seed, None, None, args.overrides)
    push = env.cfg.push
    print(f"{args.checkpoint}, {args.num_envs} episodes per preference, {pushes_in_words(push)}, "
          f"window {push.window_s:g} s {args.overrides or ''}")
    print("| Preference | Windows | Touchdowns /s | Median step (m) | COM displacement (m) |")
    print("|---|---|---|---|---|")
    for preference in evenly_spaced_preferences(args.preferences):
        r = push_response(env, policy, preference)
        shown = ", ".join(f"{x:.2f}" for x in preference)
        print(f"| ({shown}) | {r['windows']} | {r['touchdowns_per_s']:.2f} | {r['median_step']:.2f} "
              f"| {r['com_displacement']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
