"""Fingerprints of a fixed-seed G1 rollout: every observation group, reward, reward group, done flag, finished
episode's metrics and log value at every step, as SHA-256 digests of their exact bytes: one per step over all of
them (where two rollouts first part) and one per quantity over all steps (which quantities differ).

A restructuring of the env (moving code between classes, files or packages) must leave these unchanged bit for bit;
the digests are recorded once with ``python tests/g1_rollout_digest.py --write`` and compared by
tests/test_g1_rollout_regression.py. Pushes and command changes come every 0.5-1 s and the actions are seeded noise,
and episodes last 1.5 s, so a few seconds cover pushes, command resampling, falls, time-outs, resets and the
metrics of finished episodes.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os

import torch

DIGEST_FILE = os.path.join(os.path.dirname(__file__), "data", "g1_rollout_digests.json")
RECORDED_KICKS = {"g1-walk": (0.3, 2.0), "g1-fall-recovery": (0.5, 2.75)}
"""The velocity-kick ranges (m/s) of the recorded rollouts."""
TASKS = ("g1-walk", "g1-fall-recovery")
NUM_ENVS, STEPS, SEED = 4, 120, 3


def digest(value) -> str:
    """16 hex digits of SHA-256 over a tensor's dtype, shape and bytes (or a number's repr)."""
    h = hashlib.sha256()
    if isinstance(value, torch.Tensor):
        t = value.detach().cpu().contiguous()
        h.update(f"{t.dtype}{tuple(t.shape)}".encode())
        h.update(t.numpy().tobytes())
    else:
        h.update(repr(value).encode())
    return h.hexdigest()[:16]


def step_records(task: str, num_envs: int = NUM_ENVS, steps: int = STEPS, seed: int = SEED) -> list[dict]:
    """Per step, {name: digest} of everything the env returns, on the task's config with frequent pushes and
    command changes and short episodes."""
    from pchc_rsl.configs import task_config
    from pchc_rsl.envs.g1.config import ForcePushConfig
    from pchc_rsl.training.build import make_env

    cfg = task_config(task)
    cfg.num_envs, cfg.seed = num_envs, seed
    # the kicks the digests were recorded with, whatever push mix the task trains with now
    cfg.env.push.velocity_share, cfg.env.push.force = 1.0, ForcePushConfig()
    cfg.env.push.velocity = RECORDED_KICKS[task]
    cfg.env.push.interval_s = (0.5, 1.0)
    cfg.env.push.only_when_standing = False
    cfg.env.episode_length_s = 1.5
    if cfg.env.command_resample_s is not None:
        cfg.env.command_resample_s = (0.5, 1.0)
    env = make_env(cfg)
    noise = torch.Generator().manual_seed(seed)
    records = [{f"obs/{k}": digest(v) for k, v in env.get_observations().items()}]
    for _ in range(steps):
        actions = 0.8 * (2 * torch.rand(num_envs, env.num_actions, generator=noise) - 1)
        obs, reward, dones, extras = env.step(actions)
        record = {f"obs/{k}": digest(v) for k, v in obs.items()}
        record |= {"reward": digest(reward), "dones": digest(dones), "time_outs": digest(extras["time_outs"]),
                   "reward_groups": digest(extras["reward_groups"]),
                   "amp_observations": digest(extras["amp_observations"])}
        record |= {f"episode/{k}": digest(v) for k, v in sorted(extras["episode_metrics"].items())}
        record |= {f"log/{k}": digest(v) for k, v in sorted(extras["log"].items())}
        records.append(record)
    return records


def rollout_digests(task: str, names: list[str] | None = None) -> dict:
    """{"steps": [one digest per step over all its quantities], "quantities": {name: digest over all steps}}, over
    the named quantities only where ``names`` is given (a metric added since the recording is not among them)."""
    records = step_records(task)
    names = sorted(names if names is not None else {name for record in records for name in record})
    records = [{k: v for k, v in record.items() if k in names} for record in records]
    return {"steps": [digest(sorted(record.items())) for record in records],
            "quantities": {name: digest([record.get(name) for record in records]) for name in names}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help=f"record the digests into {DIGEST_FILE}")
    args = parser.parse_args()
    import mujoco

    data = {"versions": {"torch": torch.__version__, "mujoco": mujoco.__version__},
            "tasks": {task: rollout_digests(task) for task in TASKS}}
    if args.write:
        os.makedirs(os.path.dirname(DIGEST_FILE), exist_ok=True)
        with open(DIGEST_FILE, "w") as f:
            json.dump(data, f, indent=1)
        print(f"wrote {DIGEST_FILE}")
    else:
        print(json.dumps(data["versions"]))


if __name__ == "__main__":
    main()
