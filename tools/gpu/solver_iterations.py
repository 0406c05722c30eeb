"""Are 10 solver iterations enough for the G1? C MuJoCo at 10 Newton iterations against 100 on the same rollouts.

    python tools/gpu/solver_iterations.py [--tasks g1-walk-fast g1-fall-recovery] [--num-envs 64] [--steps 100]

MuJoCo Warp stops its solver at 10 iterations (inside a captured step the slowest world sets the cost of the whole
batch) and reports that most steps end there. Whether that matters is a question about the G1, not about Warp, so
it is measured on C MuJoCo: a task's env at C MuJoCo's 100 iterations (the reference) is driven by random actions
in [-1, 1] (robots get up, fall and lie: many contacts), and its physics calls are mirrored (same resets, controls,
pushes; ``envs/physics/mirror.py``) onto

- C MuJoCo at 10 iterations, put back on the reference's state after every step: the error of one policy step;
- C MuJoCo at 10 iterations running free: where the truncation carries a rollout;
- C MuJoCo at 100 iterations from start states 1e-6 rad apart: where chaos alone carries it.

Also printed: the iterations C MuJoCo's solver takes at 100 (to its tolerance), at every substep.
"""

from __future__ import annotations

import argparse
import json
import sys

import mujoco
import numpy as np
import torch

from pchc_rsl.configs import task_config
from pchc_rsl.envs.physics.batched_mujoco import STATE_SPEC, BatchedMuJoCo
from pchc_rsl.envs.physics.mirror import MirroredPhysics, edited_copies
from pchc_rsl.training.build import make_env


def iterations(count: int):
    def edit(model: mujoco.MjModel) -> None:
        model.opt.iterations = count
    return edit


class SolverCounts:
    """A mirror that steps every env with mj_step from the reference's state, substep by substep, and keeps the
    iterations its solver took (each env's warm start carried over from its own last substep, as in a rollout)."""

    device = "cpu"

    def __init__(self, reference: BatchedMuJoCo) -> None:
        self.reference, self.state = reference, reference.state.copy()
        state = torch.from_numpy(self.state)
        self.qpos, self.qvel = state[:, reference.qpos_slice], state[:, reference.qvel_slice]
        self.body_forces = None if reference.body_forces is None else reference.body_forces.clone()
        self.datas = [mujoco.MjData(model) for model in reference.models]
        self.counts: list[int] = []

    def step(self, ctrl: torch.Tensor) -> None:
        ctrl = ctrl.numpy()
        for i, (model, data) in enumerate(zip(self.reference.models, self.datas)):
            mujoco.mj_setState(model, data, self.state[i], STATE_SPEC)  # the warm start stays the env's own
            if self.body_forces is not None:
                data.xfrc_applied[:] = self.body_forces[i].numpy()
            for k in range(self.reference.substeps):
                data.ctrl[:] = ctrl[i, k] if ctrl.ndim == 3 else ctrl[i]
                mujoco.mj_step(model, data)
                self.counts.append(int(data.solver_niter[0]))
        self.state[:] = self.reference.state

    def set_qpos_qvel(self, env_ids, qpos, qvel) -> None:
        self.state[:] = self.reference.state

    def sanitize(self, envs) -> None:
        self.state[:] = self.reference.state


def measure(task: str, num_envs: int, steps: int, seed: int = 0, few: int = 10, many: int = 100) -> dict:
    cfg = task_config(task)
    cfg.num_envs, cfg.seed, cfg.device, cfg.env.physics = num_envs, seed, "cpu", "mujoco"
    env = make_env(cfg)
    c = env.physics
    reference = edited_copies(c.models, iterations(many))
    c.models[:] = reference
    truncated = edited_copies(reference, iterations(few))
    forces = c.body_forces is not None
    one_step = BatchedMuJoCo(truncated, num_envs, c.substeps, with_body_forces=forces)
    free = BatchedMuJoCo(truncated, num_envs, c.substeps, with_body_forces=forces)
    chaos = BatchedMuJoCo(reference, num_envs, c.substeps, with_body_forces=forces)
    chaos.start_offset = torch.zeros(1, c.model.nq, dtype=torch.float64)
    chaos.start_offset[:, 7:] = 1e-6
    resynced = MirroredPhysics(c, [one_step], resync=True)
    counts = SolverCounts(c)
    running = MirroredPhysics(c, [free, chaos, counts])
    env.reset()
    generator = torch.Generator().manual_seed(seed)
    step_q, step_v, speeds, free_q, chaos_q = [], [], [], [], []
    for _ in range(steps):
        env.step(2 * torch.rand(num_envs, env.num_actions, generator=generator) - 1)
        (qpos, qvel), (ref_qpos, ref_qvel) = resynced.stepped[0], resynced.reference
        step_q.append((qpos[:, 7:] - ref_qpos[:, 7:]).abs().amax(-1))
        step_v.append((qvel[:, 6:] - ref_qvel[:, 6:]).abs().amax(-1))
        speeds.append(ref_qvel[:, 6:].abs().amax(-1))
        (free_qpos, _), (chaos_qpos, _), _ = running.stepped  # since each env's last reset
        free_q.append((free_qpos[:, 7:] - ref_qpos[:, 7:]).abs().amax(-1))
        chaos_q.append((chaos_qpos[:, 7:] - ref_qpos[:, 7:]).abs().amax(-1))
    q, v, speed, needed = torch.cat(step_q), torch.cat(step_v), torch.cat(speeds), np.array(counts.counts)
    free_q, chaos_q = free_q[-1], chaos_q[-1]
    return {
        "task": task, "num_envs": num_envs, "steps": steps,
        "one_step_joint_rad": {"median": float(q.median()), "p99": float(q.quantile(0.99)), "max": float(q.max())},
        "one_step_joint_vel_rad_s": {"median": float(v.median()), "p99": float(v.quantile(0.99)),
                                     "max": float(v.max())},
        "joint_speed_rad_s_median": float(speed.median()),
        "free_run_joint_rad_median": float(free_q.median()), "chaos_joint_rad_median": float(chaos_q.median()),
        "iterations_needed": {"median": float(np.median(needed)), "p90": float(np.quantile(needed, 0.9)),
                              "max": int(needed.max()), "share_above_limit": float((needed > few).mean())},
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", nargs="+", default=["g1-walk-fast", "g1-fall-recovery"])
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--json", metavar="PATH", help="write the figures here")
    args = parser.parse_args(argv)
    results = []
    for task in args.tasks:
        r = measure(task, args.num_envs, args.steps)
        results.append(r)
        q, v, n = r["one_step_joint_rad"], r["one_step_joint_vel_rad_s"], r["iterations_needed"]
        print(f"{task}: one policy step at 10 against 100 iterations: joints median {q['median']:.1e} rad (p99 "
              f"{q['p99']:.1e}, max {q['max']:.1e}), joint velocities median {v['median']:.1e} rad/s (p99 "
              f"{v['p99']:.1e}; the fastest joint moves at {r['joint_speed_rad_s_median']:.1f} rad/s, median); "
              f"after {args.steps} steps running free (since each env's last reset): median "
              f"{r['free_run_joint_rad_median']:.1e} rad (chaos from 1e-6 rad: {r['chaos_joint_rad_median']:.1e}); "
              f"iterations C MuJoCo's solver took at 100: median {n['median']:.0f}, p90 {n['p90']:.0f}, max "
              f"{n['max']}, above 10 in {100 * n['share_above_limit']:.2f}% of substeps", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
