"""Does a style reward pull a policy that walks far from the clips? Fresh discriminators, one per setting, trained on
the clips against a checkpoint's own walking, then read along the way from its gait to the clips' posture.

    python tools/studies/amp_slope.py CKPT --motion-files CLIP [--updates 500] [--num-envs 32]

The policy's AMP windows (walking 0.5 m/s straight, pushes off, three preferences) are split by env: half train the
discriminator, half are held out. Each held-out window is then moved a share f of the way to the clips (every joint
shifted by f times the difference of the clips' mean and the gait's mean; or the sagittal leg joints alone, the
crouch), f = 0, 0.25, 0.5, 0.75, 1, and the table
gives the style reward at each f as a share of its weight c (max(0, 1 - (D - 1)^2 / 4)), the median D of the held-out
windows (f = 0) and of held-out clip windows. A discriminator whose reward stays near 0 until f is close to 1 has a
dead zone: a policy far from the clips gets no slope to climb.
"""

from __future__ import annotations

import argparse

import torch

from pchc_rsl.algorithms import MultiCriticPPO
from pchc_rsl.amp.style import AMPStyle
from pchc_rsl.evaluation import evenly_spaced_preferences, steady_walk
from pchc_rsl.evaluation.checkpoint import load_policy
from pchc_rsl.runners import load_checkpoint

SETTLE_S, MEASURE_S = 1.0, 4.0
SHARES = (0.0, 0.25, 0.5, 0.75, 1.0)
T_POSE = {"left_shoulder_roll_joint": 1.2, "right_shoulder_roll_joint": 1.2}
"""Clip frames with a shoulder rolled out further than 1.2 rad: the arms raised sideways, not walking."""
SHIPPED = {"grad_penalty_coef": 5.0, "penalty_on": "reference", "learning_rate": 1e-4, "batch_size": 512,
           "exclude_reference_beyond": None}
"""The discriminator settings the released policies trained with; every setting below starts from them (not from the
checkpoint's own, which may differ)."""
SETTINGS = {
    "reference penalty 5 (shipped)": SHIPPED,
    "reference penalty 50": {**SHIPPED, "grad_penalty_coef": 50.0},
    "interpolates penalty 5": {**SHIPPED, "penalty_on": "interpolates"},
    "interpolates penalty 50": {**SHIPPED, "penalty_on": "interpolates", "grad_penalty_coef": 50.0},
    "interpolates penalty 5, T-pose out": {**SHIPPED, "penalty_on": "interpolates", "exclude_reference_beyond": T_POSE},
    "reference penalty 5, lr 1e-5": {**SHIPPED, "learning_rate": 1e-5},
}


def walked_windows(env, policy, group: str, num_envs: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(train, held out) [n, window * joints]: the AMP windows of walking 0.5 m/s straight at three preferences,
    split by env."""
    train, held = [], []
    half = num_envs // 2
    for preference in evenly_spaced_preferences(3):
        for obs, measuring in steady_walk(env, policy, preference, (0.5, 0.0, 0.0), SETTLE_S, MEASURE_S):
            if measuring:
                train.append(obs[group][:half].clone())
                held.append(obs[group][half:].clone())
    return torch.cat(train), torch.cat(held)


def read_along_the_way(style: AMPStyle, held: torch.Tensor, reference: torch.Tensor, moved: torch.Tensor) -> dict:
    """Style reward share at each f of the way to the clips (the columns ``moved`` [window * joints] bool move),
    and the median D of the held-out windows."""
    step = (reference.mean(0) - held.mean(0)) * moved  # the clips' mean posture minus the gait's
    d = style.discriminator
    with torch.no_grad():
        shares = [float(d.style_reward(held + f * step, 1.0).mean()) for f in SHARES]
        return {"shares": shares, "d_policy": float(d(held).median()), "d_reference": float(d(reference).median())}


def joint_columns(joint_names: list[str], window: int, extra: int = 0, parts: tuple[str, ...] | None = None
                  ) -> torch.Tensor:
    """[window * (joints + extra)] bool: in every frame, the columns of the joints whose names hold one of ``parts``
    (every joint without); ``extra``: columns after the joints in each frame (the root velocity), never moved."""
    chosen = [parts is None or any(k in j for k in parts) for j in joint_names]
    return torch.tensor(chosen + [False] * extra).repeat(window)


def sagittal_leg_columns(joint_names: list[str], window: int, extra: int = 0) -> torch.Tensor:
    """The hip pitch, knee and ankle pitch columns of every frame (the crouch)."""
    return joint_columns(joint_names, window, extra, ("hip_pitch", "knee", "ankle_pitch"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoint")
    parser.add_argument("--motion-files", nargs="+", required=True)
    parser.add_argument("--updates", type=int, default=500, help="discriminator updates per setting")
    parser.add_argument("--num-envs", type=int, default=32)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    saved = load_checkpoint(args.checkpoint)
    amp_cfg = dict((saved.get("config") or {}).get("runner", {}).get("algorithm", {}).get("amp_cfg") or {})
    if not amp_cfg:
        raise SystemExit(f"amp_slope: {args.checkpoint} was trained without AMP; its AMP joints are unknown.")
    amp_cfg["motion_files"] = args.motion_files
    _, env, policy = load_policy(args.checkpoint, args.num_envs, args.seed, SETTLE_S + MEASURE_S + 1.0, None,
                                 ["env.push.enabled=false"])
    resolved = MultiCriticPPO.resolve_amp_config(amp_cfg, env.get_observations(), env)
    train, held = walked_windows(env, policy, resolved.get("obs_group", "amp"), args.num_envs)
    print(f"{args.checkpoint}: {len(train)} training and {len(held)} held-out policy windows; {args.updates} updates "
          f"per setting (batch {resolved.get('batch_size', 512)}); style reward as a share of its weight c")
    extra = train.shape[1] // resolved["window"] - len(resolved["joint_names"])  # the root velocity's columns
    paths = {"every joint": joint_columns(resolved["joint_names"], resolved["window"], extra),
             "sagittal leg joints": sagittal_leg_columns(resolved["joint_names"], resolved["window"], extra)}
    print("| discriminator | moved | " + " | ".join(f"f = {f:g}" for f in SHARES)
          + " | median D, policy | median D, clips |")
    print("|---|---|" + "---|" * (len(SHARES) + 2))
    for name, setting in SETTINGS.items():
        torch.manual_seed(args.seed)
        style = AMPStyle(**{**resolved, **setting, "num_updates": 1})
        style.replay.insert(train)
        for _ in range(args.updates):
            style.update()
        reference = style.reference.sample(4096, torch.Generator().manual_seed(args.seed + 1))
        for path, moved in paths.items():
            r = read_along_the_way(style, held, reference, moved)
            print(f"| {name} | {path} | " + " | ".join(f"{s:.3f}" for s in r["shares"])
                  + f" | {r['d_policy']:.2f} | {r['d_reference']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
