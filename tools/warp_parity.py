"""MuJoCo Warp against C MuJoCo on the same G1 walking envs: the largest joint, foot and reward differences over a
short rollout with randomised models, pushes, a mid-episode reset and an action delay, on any Warp device.

    python tools/warp_parity.py --device cuda:0        # what tools/gpu_check.sh runs
    python tools/warp_parity.py --device cpu           # Warp's CPU device (slow; the test suite does this)

Prints one line per policy step and exits non-zero when a joint differs by more than --tolerance rad (float32 Warp
against float64 C: contacts can make single envs drift apart after many steps, so the rollout is short).
"""

from __future__ import annotations

import argparse
import sys

import torch

from pchc_rsl.configs import task_config
from pchc_rsl.training.build import make_env


def main(argv: list[str] | None = None) -> float:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--num-envs", type=int, default=16)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--tolerance", type=float, default=1e-3)
    args = parser.parse_args(argv)
    envs = {}
    for backend in ("mujoco", "warp"):
        cfg = task_config("g1-walk-fast")
        cfg.num_envs, cfg.seed, cfg.device, cfg.env.physics = args.num_envs, 3, args.device, backend
        cfg.env.action_delay_s = (0.0, 0.0)  # the delayed path is compared by tests/test_physics_warp.py
        envs[backend] = make_env(cfg)
    c, w = envs["mujoco"], envs["warp"]
    generator = torch.Generator().manual_seed(0)
    worst = 0.0
    for step in range(args.steps):
        if step == 3:
            for env in envs.values():
                env.pushes.countdown[:] = 1
        if step == 10:
            for env in envs.values():
                env.reset(torch.tensor([1], device=env.device))
        actions = 0.3 * (2 * torch.rand(args.num_envs, c.num_actions, generator=generator) - 1)
        (_, reward_c, _, _), (_, reward_w, _, _) = c.step(actions), w.step(actions.to(w.device))
        joints = (c.robot.joint_pos - w.robot.joint_pos.cpu()).abs().max().item()
        feet = (c.robot.foot_pos - w.robot.foot_pos.cpu()).abs().max().item()
        rewards = (reward_c - reward_w.cpu()).abs().max().item()
        worst = max(worst, joints)
        print(f"step {step:2d}: joints {joints:.2e} rad, feet {feet:.2e} m, reward {rewards:.2e}")
    print(f"warp_parity: largest joint difference {worst:.2e} rad over {args.steps} steps on {args.device} "
          f"({'within' if worst <= args.tolerance else 'ABOVE'} {args.tolerance:g})")
    if worst > args.tolerance:
        sys.exit(1)
    return worst


if __name__ == "__main__":
    main()
