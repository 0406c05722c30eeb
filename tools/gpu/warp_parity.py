"""MuJoCo Warp against C MuJoCo on the same physics inputs, on any Warp device: a check of the physics alone.

    python tools/gpu/warp_parity.py --device cuda:0                  # what tools/gpu/gpu_check.sh runs
    python tools/gpu/warp_parity.py --device cpu --num-envs 4        # Warp's CPU device (slow; the tests do this)
    python tools/gpu/warp_parity.py --device cuda:0 --perturb-gains 0.05   # self-check: must fail

A G1 env on C MuJoCo draws everything random (randomised models, start states, commands, pushes, action delays) on
the CPU, and each call it makes into its physics is mirrored onto a MuJoCo Warp physics on --device built from the
same model variants: the same resets, the same controls and body forces, and the same velocity kicks (what the env
wrote into the state between two steps). Comparing two envs instead would compare their random draws: a CPU and a
CUDA torch.Generator with one seed give different numbers. C MuJoCo runs at Warp's solver settings, so what
differs is float32 against float64 and each implementation's own arithmetic.

Contacts are chaotic: one env can drift apart after many steps while the rest agree. So the figure judged is the
median over envs of each env's largest joint difference (rad), at every policy step; the worst env is printed
beside it, and so is C MuJoCo against itself from start states 1e-6 rad apart (the chaos floor). Exits 1 when the
median exceeds --tolerance at any step.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable

import mujoco
import torch

from pchc_rsl.configs import task_config
from pchc_rsl.envs.physics.batched_mujoco import BatchedMuJoCo
from pchc_rsl.envs.physics.mirror import MirroredPhysics, edited_copies
from pchc_rsl.training.build import make_env

CHAOS_OFFSET = 1e-6
"""rad added to every joint of the C twin's start states: how far apart chaos alone carries two rollouts."""


def solver_as_warp(settings) -> Callable[[mujoco.MjModel], None]:
    def edit(model: mujoco.MjModel) -> None:
        model.opt.iterations, model.opt.ls_iterations = settings.solver_iterations, settings.linesearch_iterations
    return edit


def gains_scaled(scale: float) -> Callable[[mujoco.MjModel], None]:
    """Every actuator's kp and kd times 1 + scale: a physics that differs."""
    def edit(model: mujoco.MjModel) -> None:
        model.actuator_gainprm[:, 0] *= 1 + scale
        model.actuator_biasprm[:, 1:3] *= 1 + scale
    return edit


def compare(task: str = "g1-walk-fast", device: str = "cuda:0", num_envs: int = 64, steps: int = 20, seed: int = 3,
            perturb_gains: float = 0.0) -> list[dict]:
    """Per policy step: median and largest (over envs) joint difference of Warp from C MuJoCo, and of C MuJoCo from
    itself started 1e-6 rad apart (rad)."""
    from pchc_rsl.envs.physics.warp_mujoco import WarpMuJoCo

    cfg = task_config(task)
    cfg.num_envs, cfg.seed, cfg.device, cfg.env.physics = num_envs, seed, "cpu", "mujoco"
    settings = cfg.env.warp
    env = make_env(cfg)
    c = env.physics
    models = edited_copies(c.models, solver_as_warp(settings))
    c.models[:] = models
    warp_models = edited_copies(models, gains_scaled(perturb_gains)) if perturb_gains else models
    warp = WarpMuJoCo(warp_models, num_envs, c.substeps, device, with_body_forces=c.body_forces is not None,
                      settings=settings)
    twin = BatchedMuJoCo(models, num_envs, c.substeps, with_body_forces=c.body_forces is not None)
    twin.start_offset = torch.zeros(1, c.model.nq, dtype=torch.float64)
    twin.start_offset[:, 7:] = CHAOS_OFFSET  # every joint
    MirroredPhysics(c, [warp, twin])
    env.reset()  # every env starts again: the start states reach the mirrors
    generator = torch.Generator().manual_seed(0)
    rows = []
    for step in range(steps):
        if step == 3:
            env.pushes.countdown[:] = 1  # every env is pushed now
        if step == 10:
            env.reset(torch.tensor([1]))  # a mid-episode reset
        actions = 2 * torch.rand(num_envs, env.num_actions, generator=generator) - 1
        env.step(actions)
        joints = c.qpos[:, 7:]
        warp_error = (warp.qpos[:, 7:].double().cpu() - joints).abs().amax(-1)
        chaos = (twin.qpos[:, 7:] - joints).abs().amax(-1)
        rows.append({"step": step, "median": float(warp_error.median()), "worst": float(warp_error.max()),
                     "chaos_median": float(chaos.median()), "chaos_worst": float(chaos.max())})
    warp.overflow_report()  # an overflow would make the comparison meaningless: it raises
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="g1-walk-fast")
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--tolerance", type=float, default=1e-4,
                        help="largest median joint difference allowed at any step, rad (default 1e-4)")
    parser.add_argument("--perturb-gains", type=float, default=0.0, metavar="SCALE",
                        help="self-check: Warp's actuators get kp and kd times 1 + SCALE; the check must then fail")
    parser.add_argument("--json", metavar="PATH", help="write the per-step figures here")
    args = parser.parse_args(argv)
    rows = compare(args.task, args.device, args.num_envs, args.steps, perturb_gains=args.perturb_gains)
    for r in rows:
        print(f"step {r['step']:2d}: Warp - C median {r['median']:.1e} rad, worst env {r['worst']:.1e}; C - C "
              f"(start 1e-6 apart) median {r['chaos_median']:.1e}, worst {r['chaos_worst']:.1e}", flush=True)
    worst = max(r["median"] for r in rows)
    ok = worst <= args.tolerance
    print(f"warp_parity: {args.task} on {args.device}, {args.num_envs} envs: largest median joint difference "
          f"{worst:.1e} rad over {args.steps} steps ({'within' if ok else 'ABOVE'} {args.tolerance:g}); worst env "
          f"{max(r['worst'] for r in rows):.1e} rad (C against itself: {max(r['chaos_worst'] for r in rows):.1e})",
          flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"task": args.task, "device": args.device, "tolerance": args.tolerance, "ok": ok,
                       "largest_median": worst, "steps": rows}, f, indent=2)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
