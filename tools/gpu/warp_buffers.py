"""How large MuJoCo Warp's per-world buffers must be for the G1 tasks, and what they cost.

    python tools/gpu/warp_buffers.py [--device cpu] [--num-envs 128] [--steps 100] [--memory-envs 4096]

Runs robots that lie, get up and fall, on Warp and on C MuJoCo with the same draws (both on the CPU when --device
is cpu: Warp's CPU device makes the same contacts as a GPU), and prints per scenario the largest constraint rows of
one world (Warp: after every physics substep, and at policy steps; C MuJoCo: at policy steps), the largest contacts
of one world, and the share of substeps whose solver stopped at its iteration limit:

- fall-recovery: the task itself (prone or supine starts, HoST's assist), random actions in [-1, 1];
- walk lying: g1-walk-fast with its robots started lying (prone or supine, random yaw), random actions;
- walk falling: g1-walk-fast from standing, random actions, terminations off (they fall and stay down);
- walk lying still: lying robots holding a zero action.

Then the memory of Warp's buffers (its Data and the solver's per-step arrays) at --memory-envs worlds for a few
sizes, counted from the arrays mujoco_warp allocates.
"""

from __future__ import annotations

import argparse
import math
import sys

import mujoco
import numpy as np
import torch

from pchc_rsl.training.build import make_env
from pchc_rsl.configs import task_config
from pchc_rsl.envs.physics.batched_mujoco import STATE_SPEC

SCENARIOS = {
    "fall-recovery": ("g1-fall-recovery", "task", "random"),
    "walk lying": ("g1-walk-fast", "lying", "random"),
    "walk falling": ("g1-walk-fast", "standing", "random"),
    "walk lying still": ("g1-walk-fast", "lying", "zero"),
}


def lying_states(env, env_ids: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The env's own start with the pelvis at 0.3 m, face down or face up at random, random yaw."""
    qpos, qvel = type(env).initial_state(env, env_ids)
    n = len(env_ids)
    g = env.generator
    pitch = torch.where(torch.rand(n, generator=g, device=env.device) < 0.5, math.pi / 2, -math.pi / 2)
    yaw = 2 * math.pi * torch.rand(n, generator=g, device=env.device)
    cy, sy, cp, sp = (yaw / 2).cos(), (yaw / 2).sin(), (pitch / 2).cos(), (pitch / 2).sin()
    qpos[:, 3:7] = torch.stack([cy * cp, -sy * sp, cy * sp, sy * cp], -1).double()
    qpos[:, 2] = 0.3
    return qpos, qvel


def build(task: str, start: str, physics: str, device: str, num_envs: int, seed: int):
    cfg = task_config(task)
    cfg.num_envs, cfg.seed, cfg.device, cfg.env.physics = num_envs, seed, device, physics
    if task == "g1-fall-recovery":
        cfg.env.supine_probability = 0.5
    else:  # robots on the floor stay there: no terminations
        cfg.env.termination_height, cfg.env.termination_tilt = -1e9, 1e9
    cfg.env.warp.constraints_per_env, cfg.env.warp.contacts_per_env = 512, 128  # room for any peak
    env = make_env(cfg)
    if start == "lying":
        env.initial_state = lambda ids: lying_states(env, ids)
        env.reset()
    if physics == "warp":
        env.physics.overflow_report()  # the peaks of the rollout alone
    return env


class CounterC:
    """Constraint rows and contacts of each C MuJoCo env at a policy step (mj_forward on its state)."""

    def __init__(self, physics) -> None:
        self.physics, self.data = physics, mujoco.MjData(physics.model)
        self.rows = self.contacts = 0

    def sample(self) -> None:
        p, d = self.physics, self.data
        for i, model in enumerate(p.models):
            mujoco.mj_setState(model, d, p.state[i], STATE_SPEC)
            mujoco.mj_forward(model, d)
            self.rows, self.contacts = max(self.rows, d.nefc), max(self.contacts, d.ncon)


class CounterWarp:
    """Constraint rows and contacts of each Warp world at a policy step (every substep: the physics' own record)."""

    def __init__(self, physics) -> None:
        import warp as wp

        self.physics = physics
        self.nefc, self.nacon = wp.to_torch(physics.data.nefc), wp.to_torch(physics.data.nacon)
        self.worldid = wp.to_torch(physics.data.contact.worldid)
        self.rows = self.contacts = 0

    def sample(self) -> None:
        n = int(self.nacon[0])
        counts = torch.bincount(self.worldid[:n].long(), minlength=self.physics.num_envs)
        self.rows = max(self.rows, int(self.nefc.max()))
        self.contacts = max(self.contacts, int(counts.max()))


def run(scenario: str, device: str, num_envs: int, steps: int, seed: int) -> dict:
    task, start, actions = SCENARIOS[scenario]
    result = {"scenario": scenario}
    for physics in ("mujoco", "warp"):
        env = build(task, start, physics, device if physics == "warp" else "cpu", num_envs, seed)
        counter = CounterWarp(env.physics) if physics == "warp" else CounterC(env.physics)
        generator = torch.Generator().manual_seed(seed)
        for _ in range(steps):
            a = (2 * torch.rand(num_envs, env.num_actions, generator=generator) - 1 if actions == "random"
                 else torch.zeros(num_envs, env.num_actions))
            env.step(a.to(env.device))
            counter.sample()
        result[f"{physics}_rows_at_steps"], result[f"{physics}_contacts"] = counter.rows, counter.contacts
        if physics == "warp":
            report = env.physics.overflow_report()
            result["warp_rows_every_substep"] = int(report["max_constraint_rows"])
            result["warp_mean_contacts_peak"] = report["max_contacts"] / num_envs
            result["solver_limit_share"] = report["solver_limit_share"]
        del env
    return result


def buffer_bytes(model: mujoco.MjModel, nworld: int, constraints: int, contacts: int, device: str) -> tuple[int, int]:
    """Bytes of mujoco_warp's Data, and of the arrays its step allocates (the solver's; kept by a captured graph)."""
    import dataclasses

    import mujoco_warp as mjw
    import warp as wp

    def size(value, seen) -> int:
        if isinstance(value, wp.array):
            if id(value) in seen:
                return 0
            seen.add(id(value))
            return value.capacity
        if dataclasses.is_dataclass(value):
            return sum(size(getattr(value, f.name), seen) for f in dataclasses.fields(value))
        return 0

    with wp.ScopedDevice(device):
        wp_model = mjw.put_model(model)
        data = mjw.make_data(model, nworld=nworld, nconmax=contacts, njmax=constraints)
        allocated = []
        originals = {name: getattr(wp, name) for name in ("empty", "zeros", "full", "ones")}

        def counting(name):
            def allocate(*args, **kwargs):
                array = originals[name](*args, **kwargs)
                allocated.append(array.capacity)
                return array
            return allocate

        for name in originals:
            setattr(wp, name, counting(name))
        try:
            mjw.step(wp_model, data)
        finally:
            for name, original in originals.items():
                setattr(wp, name, original)
        return size(data, set()), sum(allocated)


def memory(task: str, num_envs: int, sizes: list[tuple[int, int]], device: str) -> list[dict]:
    """Data and per-step bytes at ``num_envs`` worlds, from two small batches (both grow linearly with worlds)."""
    from pchc_rsl.robots.g1.model import build_g1_model

    cfg = task_config(task)
    model = build_g1_model(cfg.env.joints, cfg.env.timestep, held_joints=tuple(cfg.env.held_joints))
    rows = []
    for constraints, contacts in sizes:
        small, large = (buffer_bytes(model, n, constraints, contacts, device) for n in (16, 32))
        at = [a + (b - a) * (num_envs - 16) / 16 for a, b in zip(small, large)]
        rows.append({"task": task, "constraints_per_env": constraints, "contacts_per_env": contacts,
                     "data_mb": at[0] / 2**20, "step_mb": at[1] / 2**20})
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", default="cpu", help="Warp's device (default cpu)")
    parser.add_argument("--num-envs", type=int, default=128)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scenarios", nargs="*", default=list(SCENARIOS), choices=list(SCENARIOS))
    parser.add_argument("--memory-envs", type=int, default=4096)
    parser.add_argument("--sizes", nargs="+", default=["64x16", "128x32", "160x48", "300x64"],
                        help="constraint rows x contacts per world to price (default 64x16 128x32 160x48 300x64)")
    args = parser.parse_args(argv)
    for scenario in args.scenarios:
        r = run(scenario, args.device, args.num_envs, args.steps, args.seed)
        print(f"{scenario:17s} rows: Warp {r['warp_rows_every_substep']} (every substep), {r['warp_rows_at_steps']} "
              f"(policy steps), C {r['mujoco_rows_at_steps']} (policy steps); contacts of one world: Warp "
              f"{r['warp_contacts']}, C {r['mujoco_contacts']}; Warp's all-world peak {r['warp_mean_contacts_peak']:.1f} "
              f"per world; solver at its limit {r['solver_limit_share']:.1f}% of world-substeps", flush=True)
    sizes = [tuple(int(x) for x in size.split("x")) for size in args.sizes]
    for task in ("g1-walk-fast", "g1-fall-recovery"):
        for row in memory(task, args.memory_envs, sizes, args.device):
            print(f"memory {task:16s} {row['constraints_per_env']:4d} rows x {row['contacts_per_env']:3d} contacts per "
                  f"world at {args.memory_envs} worlds: Data {row['data_mb']:7.0f} MB, step arrays "
                  f"{row['step_mb']:6.0f} MB", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
