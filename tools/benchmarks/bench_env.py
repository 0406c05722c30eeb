"""The G1 envs against the bare batched physics they are built on, their contacts, and their memory at scale.

    python tools/benchmarks/bench_env.py [--num-envs 64 256 1024] [--threads 1 2]  # steps/s standing, lying; contacts
    python tools/benchmarks/bench_env.py --memory 1024 4096                          # build time, peak RSS at scale

Speed: for each task, N and thread count, in the same run: (a) env.step with a held default-pose action
(observations, rewards, contacts, pushes, resets: everything a training step does) and (b) BatchedMuJoCo.step alone
on the same compiled model from the same states with the same control: the physics limit. Standing is g1-walk
(robots start upright with both feet on the ground), lying is g1-fall-recovery (robots start prone). Prints medians
of repeats and the ratio env / bare. Contacts: per robot after 0.5 s, the floor contacts of each foot and of every
geom, from mj_forward on the env's states. Memory: each N in its own process under /usr/bin/time -v: the time to
build N randomised g1-walk-fast envs and the runner, one training iteration, and the process' peak RSS.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import time

import mujoco
import numpy as np
import torch

from pchc_rsl.configs import task_config
from pchc_rsl.envs.physics.batched_mujoco import BatchedMuJoCo
from pchc_rsl.training.build import make_env

POSTURES = {"standing": "g1-walk", "lying": "g1-fall-recovery"}


def build(task: str, num_envs: int, threads: int):
    cfg = task_config(task)
    cfg.num_envs = num_envs
    cfg.env.num_threads = threads
    cfg.env.randomization.enabled = False  # one model, as the bare loop uses
    return make_env(cfg)


def measure(task: str, num_envs: int, threads: int, steps: int, repeats: int) -> tuple[float, float]:
    env = build(task, num_envs, threads)
    bare = BatchedMuJoCo(env.model, num_envs, env.cfg.decimation, threads, with_body_forces=True)
    action = torch.zeros(num_envs, env.num_actions)
    ctrl = env.default_joint_pos.double().expand(num_envs, -1).numpy().copy()
    env_times, bare_times = [], []
    for _ in range(repeats):
        env.reset()
        start_state = env.physics.state.copy()
        start = time.perf_counter()
        for _ in range(steps):
            env.step(action)
        env_times.append(time.perf_counter() - start)
        bare.state[:] = start_state
        start = time.perf_counter()
        for _ in range(steps):
            bare.step(ctrl)
        bare_times.append(time.perf_counter() - start)
    return num_envs * steps / statistics.median(env_times), num_envs * steps / statistics.median(bare_times)


def contacts(task: str, num_envs: int = 8, steps: int = 25) -> tuple[float, float, float, float]:
    """Mean per robot after ``steps`` policy steps: floor contacts of the left foot, the right foot, all geoms, and
    of mesh geoms."""
    env = build(task, num_envs, 1)
    for _ in range(steps):
        env.step(torch.zeros(num_envs, env.num_actions))
    m = env.model
    data, floor = mujoco.MjData(m), m.geom("floor").id
    feet = [m.body(name).id for name in ("left_ankle_roll_link", "right_ankle_roll_link")]
    rows = []
    for i in range(num_envs):
        mujoco.mj_setState(m, data, env.physics.state[i], mujoco.mjtState.mjSTATE_FULLPHYSICS)
        mujoco.mj_forward(m, data)
        robot_geoms = [c.geom2 if c.geom1 == floor else c.geom1 for c in data.contact[: data.ncon]]
        bodies = [m.geom_bodyid[g] for g in robot_geoms]
        meshes = sum(m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH for g in robot_geoms)
        rows.append((bodies.count(feet[0]), bodies.count(feet[1]), data.ncon, meshes))
    return tuple(np.mean(rows, axis=0))


def memory_run(num_envs: int) -> None:
    """One process: build N randomised envs and a runner, train one iteration, print the timings."""
    import tempfile

    from pchc_rsl.training.build import make_runner

    cfg = task_config("g1-walk-fast")
    cfg.num_envs = num_envs
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as log_dir:
        runner = make_runner(cfg, log_dir)
        built = time.perf_counter() - start
        start = time.perf_counter()
        runner.learn(1)
        print(f"build_s {built:.1f} iteration_s {time.perf_counter() - start:.1f}", flush=True)


def memory(num_envs: int) -> str:
    command = ["/usr/bin/time", "-v", sys.executable, os.path.abspath(__file__), "--memory-run", str(num_envs)]
    out = subprocess.run(command, capture_output=True, text=True)
    timings = re.search(r"build_s (\S+) iteration_s (\S+)", out.stdout)
    peak = re.search(r"Maximum resident set size \(kbytes\): (\d+)", out.stderr)
    if out.returncode != 0 or not timings or not peak:
        return f"{num_envs:>6}  failed (exit {out.returncode}): {out.stderr.strip().splitlines()[-1:]}"
    return f"{num_envs:>6}{float(timings[1]):>10.1f}{float(timings[2]):>14.1f}{int(peak[1]) / 2**20:>16.2f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--num-envs", type=int, nargs="+", default=[64, 256, 1024])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--steps", type=int, default=20, help="policy steps per timing (0.4 s)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--postures", nargs="+", default=list(POSTURES), choices=list(POSTURES))
    parser.add_argument("--memory", type=int, nargs="+", metavar="N", help="measure build time and peak RSS instead")
    parser.add_argument("--memory-run", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.memory_run:
        memory_run(args.memory_run)
        return
    if args.memory:
        print("g1-walk-fast, randomised, one training iteration (24 steps per env); peak RSS of the process")
        print(f"{'N':>6}{'build s':>10}{'iteration s':>14}{'peak RSS GiB':>16}")
        for n in args.memory:
            print(memory(n), flush=True)
        return
    for posture in args.postures:
        task = POSTURES[posture]
        left, right, total, meshes = contacts(task)
        print(f"{task} ({posture}): floor contacts per robot after 0.5 s: left foot {left:.1f}, right foot {right:.1f}, "
              f"all {total:.1f}, through meshes {meshes:.1f}")
        print(f"policy steps/s (env steps, all envs), median of {args.repeats}")
        print(f"{'N':>6}{'threads':>9}{'env':>12}{'bare physics':>14}{'env/bare':>10}")
        for n in args.num_envs:
            for threads in args.threads:
                env_rate, bare_rate = measure(task, n, threads, args.steps, args.repeats)
                print(f"{n:>6}{threads:>9}{env_rate:>12.0f}{bare_rate:>14.0f}{env_rate / bare_rate:>10.2f}", flush=True)


if __name__ == "__main__":
    main()
