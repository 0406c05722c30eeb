"""pchc-train: train a preference-conditioned policy on a registered task."""

from __future__ import annotations

import argparse
import datetime
import os

from pchc_rsl.configs import ACTOR_CLASSES, TASKS, select_actor, task_config
from pchc_rsl.preference import validate_preference


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pchc-train",
        description="Train PCHC (MultiCriticPPO + PCI actor) on a task. Known tasks: " + ", ".join(sorted(TASKS)),
    )
    parser.add_argument("--task", required=True, help="task name: " + ", ".join(sorted(TASKS)))
    parser.add_argument("--num-envs", type=int, help="parallel environments (default: the task's)")
    parser.add_argument("--max-iterations", type=int, help="PPO iterations (default: the task's)")
    parser.add_argument("--seed", type=int, help="random seed (default: the task's)")
    parser.add_argument("--device", help="torch device, e.g. cpu or cuda:0 (default: the task's)")
    parser.add_argument("--actor", choices=sorted(ACTOR_CLASSES), help="actor variant (default: pci)")
    parser.add_argument("--fixed-preference", metavar="L1,L2",
                        help="hold lambda constant during training (baselines); required by --actor no-preference")
    parser.add_argument("--motion-files", nargs="+", metavar="PATH",
                        help="reference motions for the AMP style reward (files or folders: LAFAN1 G1 CSV, npz)")
    parser.add_argument("--log-dir", help="where checkpoints and TensorBoard events go (default: logs/TASK/DATE)")
    parser.add_argument("--resume", metavar="CKPT", help="checkpoint to continue from")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    try:
        cfg = task_config(args.task)
    except ValueError as error:
        raise SystemExit(f"pchc-train: {error}")
    if args.num_envs is not None:
        cfg.num_envs = args.num_envs
    if args.max_iterations is not None:
        cfg.runner.max_iterations = args.max_iterations
    if args.seed is not None:
        cfg.seed = args.seed
    if args.device is not None:
        cfg.device = args.device
    if args.actor is not None:
        select_actor(cfg.runner.actor, args.actor)
    if args.motion_files:
        if cfg.runner.algorithm.amp_cfg is None:
            raise SystemExit(f"pchc-train: task '{cfg.name}' has no AMP style reward; drop --motion-files.")
        cfg.runner.algorithm.amp_cfg.motion_files = list(args.motion_files)
    if args.fixed_preference is not None:
        try:
            lam = validate_preference([float(x) for x in args.fixed_preference.split(",")], len(cfg.env.objective_names))
        except ValueError as error:
            raise SystemExit(f"pchc-train: --fixed-preference {args.fixed_preference}: {error}")
        cfg.fixed_preference = lam.tolist()
    if args.actor == "no-preference":
        if cfg.fixed_preference is None:
            raise SystemExit("pchc-train: --actor no-preference trains one fixed weighting; give --fixed-preference.")
        cfg.runner.obs_groups["actor"] = [g for g in cfg.runner.obs_groups["actor"] if g != "preference"]
    log_dir = args.log_dir or os.path.join(
        "logs", cfg.name, datetime.datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
    )
    from pchc_rsl.cli.common import make_runner

    runner = make_runner(cfg, log_dir)
    if args.resume:
        runner.load(args.resume)
    runner.learn(cfg.runner.max_iterations)
    print(f"pchc-train: checkpoints and TensorBoard events in {log_dir}")


if __name__ == "__main__":
    main()
