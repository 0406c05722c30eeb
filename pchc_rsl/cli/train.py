"""pchc-train: train a preference-conditioned policy on a registered task, or continue a checkpoint."""

from __future__ import annotations

import argparse
import copy
import datetime
import json
import os
import re
import shlex
import signal
import sys
import time

from pchc_rsl.cli import arguments
from pchc_rsl.configs import ACTOR_CLASSES, TASKS, select_actor, task_config
from pchc_rsl.configs.base import LOGGERS
from pchc_rsl.evaluation import TASK_EVALUATION
from pchc_rsl.preference import validate_preference
from pchc_rsl.runners import NonFiniteTraining, PhysicsOverflowStopped, TrainingInterrupted, load_checkpoint
from pchc_rsl.training.build import make_runner, restore_config, saved_config
from pchc_rsl.training.checks import check_task_config
from pchc_rsl.training.overrides import apply_overrides, config_fields, format_config, set_value
from pchc_rsl.training.run_folder import checkpoints_in, first_missing_folder, new_run_folder, remove_if_unused
from pchc_rsl.training.threads import apply_threads
from pchc_rsl.utils.distributed import DistributedSetupError, world

PROG = "pchc-train"
INIT_FROM_PARTS = {"actor": True, "critic": True, "amp": True, "optimizer": False, "iteration": False, "rnd": False}
"""What --init-from takes from its checkpoint: the networks (with their normalisers), not the training progress."""
OVERRIDE_SHAPE = re.compile(r"^[A-Za-z_][\w.]*=")


def build_parser(task_help: str = "") -> argparse.ArgumentParser:
    parser = arguments.Parser(
        prog=PROG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Train PCHC (MultiCriticPPO + PCI actor) on a task, or continue a checkpoint with --resume.\n"
        "Any field of the task's config can be set with KEY=VALUE (e.g. runner.algorithm.learning_rate=3e-4 "
        "env.push.interval_s=2,4);\n`pchc-train --task TASK --help` lists them all with their values.",
        epilog=task_help,
    )
    parser.add_argument("overrides", nargs="*", metavar="KEY=VALUE", help="set any config field (see above)")
    parser.add_argument("--task", help="task name: " + ", ".join(sorted(TASKS)) + " (with --resume: the checkpoint's)")
    parser.add_argument("--num-envs", type=arguments.positive_int, help="parallel environments (default: the task's)")
    parser.add_argument("--max-iterations", type=arguments.positive_int,
                        help="PPO iterations to run (default: the task's). With --resume these are additional "
                        "iterations: model_9.pt + 10 ends at model_19.pt")
    parser.add_argument("--seed", type=arguments.seed, help="random seed (default: the task's)")
    parser.add_argument("--device", help="torch device, e.g. cpu or cuda:0 (default: the task's)")
    parser.add_argument("--threads", type=arguments.positive_int,
                        help="CPU threads for the physics (while collecting) and torch (while learning); default: "
                             "the cores this process may use")
    parser.add_argument("--physics", choices=["mujoco", "warp"],
                        help="G1 physics: C MuJoCo on CPU threads (default) or MuJoCo Warp on --device (the "
                        "pchc-rsl[warp] extra)")
    parser.add_argument("--actor", choices=sorted(ACTOR_CLASSES), help="actor variant (default: pci)")
    parser.add_argument("--fixed-preference", type=arguments.preference, metavar="L1,L2",
                        help="hold lambda constant during training (baselines); required by --actor no-preference")
    parser.add_argument("--motion-files", nargs="+", metavar="PATH",
                        help="reference motions for the AMP style reward (files or folders: LAFAN1 G1 CSV, npz)")
    parser.add_argument("--log-dir", help="a new (or empty) folder for this run's checkpoints and TensorBoard events "
                        "(default: logs/TASK/DATE)")
    parser.add_argument("--logger", choices=sorted(LOGGERS), help="where training scalars go (default: tensorboard)")
    parser.add_argument("--logger-project", metavar="NAME", help="W&B / Neptune project (default: the experiment)")
    parser.add_argument("--resume", metavar="CKPT",
                        help="continue this checkpoint (or a run folder's latest) in a new run folder, with its "
                        "config; flags and KEY=VALUE given here override it")
    parser.add_argument("--init-from", metavar="CKPT",
                        help="a new run of --task's config (with flags and KEY=VALUE) whose networks start from "
                        "this checkpoint's weights (actor, critics, AMP discriminator): fine-tuning after a reward "
                        "or environment change; fresh optimizer, iterations from 0")
    parser.add_argument("--fresh-discriminator", action="store_true",
                        help="with --init-from: start the AMP discriminator afresh instead of from the checkpoint's "
                        "(one trained on a gait far from the clips tells every new window apart and pays no style)")
    parser.add_argument("--show-config", action="store_true", help="print the resolved config and exit")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="also print the models, rsl-rl's full per-iteration block and error tracebacks")
    return parser


def main(argv: list[str] | None = None) -> None:
    if world()[1] != 0:  # torchrun: rank 0 speaks for the run; the others print only errors
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - for the life of the process
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(_task_help(argv)).parse_intermixed_args(argv)  # KEY=VALUE words may surround the options
    _take_overrides_from_motion_files(args)

    try:
        cfg, config, notes = resolve(args)
        if args.show_config:
            print(format_config(cfg))
            return
        log_dir = new_run_folder(args.log_dir, cfg.name)
    except (ValueError, FileNotFoundError) as error:
        if args.verbose:
            raise
        raise SystemExit(f"{PROG}: {error}") from None
    if not args.resume and config["overrides"]:  # a resumed run lists them in its 'continuing' note
        notes.append("overrides of the task's config: " + " ".join(config["overrides"]))
    for note in notes:
        print(f"{PROG}: {note}")
    train(cfg, config, log_dir, args)


def resolve(args) -> tuple:
    """The TaskConfig to train (the task's, or the checkpoint's with --resume), flags and KEY=VALUE overrides
    applied and checked; the config dict checkpoints will carry; lines to tell the user."""
    notes = []
    if args.resume and args.init_from:
        raise ValueError("give --resume (continue a run with its config) or --init-from (a new run starting from its "
                         "weights), not both.")
    if args.fresh_discriminator and not args.init_from:
        raise ValueError("--fresh-discriminator applies to --init-from (a run continued with --resume keeps its "
                         "discriminator).")
    if args.resume and os.path.isdir(args.resume):  # a run folder: its latest checkpoint, as legged_gym does

        found = checkpoints_in(args.resume)
        if not found:
            raise ValueError(f"--resume {args.resume}: the folder holds no model_<it>.pt checkpoint.")
        args.resume = found[-1]
        notes.append(f"--resume of a folder: its latest checkpoint, {args.resume}")
    if args.resume:
        saved = saved_config(args.resume, load_checkpoint(args.resume))
        if args.task is not None and args.task != saved["task"]:
            raise ValueError(f"--task {args.task}, but {args.resume} was trained on '{saved['task']}'.")
        cfg = restore_config(saved)
    elif args.task is None:
        raise ValueError("give --task TASK (one of " + ", ".join(sorted(TASKS)) + ") or --resume CKPT.")
    else:
        cfg = task_config(args.task)
    before = copy.deepcopy({k: v[3] for k, v in config_fields(cfg, aliases=False).items()})

    flags = []
    for flag, key in (("num_envs", "num_envs"), ("max_iterations", "runner.max_iterations"), ("seed", "seed"),
                      ("device", "device"), ("logger", "runner.logger"), ("logger_project", "runner.logger_project")):
        if getattr(args, flag) is not None:
            flags.append(f"{key}={getattr(args, flag)}")
    if args.physics is not None:
        if not hasattr(cfg.env, "physics"):
            raise ValueError(f"task '{cfg.name}' has one physics; --physics applies to the G1 tasks.")
        flags.append(f"env.physics={args.physics}")
    if args.actor is not None:
        select_actor(cfg.runner.actor, args.actor)
        if args.actor == "no-preference":
            cfg.runner.obs_groups["actor"] = [g for g in cfg.runner.obs_groups["actor"] if g != "preference"]
    if args.motion_files:
        if cfg.runner.algorithm.amp_cfg is None:
            raise ValueError(f"task '{cfg.name}' has no AMP style reward; drop --motion-files.")
        cfg.runner.algorithm.amp_cfg.motion_files = list(args.motion_files)
    for item in flags:
        key, _, text = item.partition("=")
        given = [o for o in args.overrides if o.partition("=")[0].strip() == key]
        if given:  # e.g. --num-envs 16 with num_envs=8
            flag = "--" + key.rsplit(".", 1)[-1].replace("_", "-")
            raise ValueError(f"{key} is given twice: {flag} {text} and {given[0]}; give it once.")
        set_value(cfg, key, text)
    apply_overrides(cfg, args.overrides)
    if args.fixed_preference is not None:
        cfg.fixed_preference = args.fixed_preference
    if cfg.fixed_preference is not None:
        try:
            lam = validate_preference(cfg.fixed_preference, len(cfg.env.objective_names))
        except ValueError as error:
            raise ValueError(f"fixed preference {cfg.fixed_preference}: {error}") from None
        cfg.fixed_preference = lam.tolist()
    if "preference" not in cfg.runner.obs_groups["actor"] and cfg.fixed_preference is None:
        raise ValueError("--actor no-preference trains one fixed weighting; give --fixed-preference.")
    check_task_config(cfg)

    after = {k: v[3] for k, v in config_fields(cfg, aliases=False).items()}
    changed = _most_specific([k for k, v in after.items() if before.get(k) != v], before, after)
    if args.resume:
        shown = ", ".join(f"{k} {_show(before.get(k))} -> {_show(after[k])}" for k in changed)
        notes.append(f"continuing {args.resume} with its config" + (f"; overridden: {shown}" if shown else ""))
    amp = cfg.runner.algorithm.amp_cfg
    if amp is not None and not amp.motion_files:
        notes.append("AMP is off: no --motion-files given (see docs/training.md, AMP).")
    if amp is not None and args.resume and not args.motion_files:
        missing = [path for path in amp.motion_files if not os.path.exists(path)]
        if missing:  # a released checkpoint names its clips by file name only
            raise ValueError(f"{args.resume} names the motion clip {missing[0]}, which is not here; give the "
                             "clips with --motion-files.")
    config = cfg.to_dict()
    # what differs from the task's defaults (resuming: from the checkpoint's config), as KEY=VALUE
    config["overrides"] = [f"{k}={_show(after[k])}" for k in changed]
    if args.resume:
        config["resumed_from"] = os.path.abspath(args.resume)
    if args.init_from:
        load_checkpoint(args.init_from)  # unreadable: refused here, before a run folder exists
        config["initialised_from"] = os.path.abspath(args.init_from)
        notes.append(f"networks start from {args.init_from}'s weights; fresh optimizer, iterations from 0"
                     + ("; fresh discriminator" if args.fresh_discriminator else ""))
    return cfg, config, notes


def _most_specific(changed: list[str], before: dict, after: dict) -> list[str]:
    """The changed keys without a dict whose entries say the same: ``a.b.c=1`` rather than also ``a.b={...}``. A dict
    that gained or lost keys stays listed whole, so its shape change is not lost."""
    def described_by_entries(key: str) -> bool:
        old, new = before.get(key), after[key]
        return (isinstance(old, dict) and isinstance(new, dict) and old.keys() == new.keys()
                and any(other.startswith(key + ".") for other in changed))
    return [k for k in changed if not described_by_entries(k)]


def train(cfg, config: dict, log_dir: str, args) -> None:
    """Build, train, and close with a summary; a failed run that saved no checkpoint leaves no folder behind."""
    created = first_missing_folder(log_dir)
    owns_folder = world()[1] == 0  # torchrun: the run folder is rank 0's; a failing rank > 0 leaves it alone

    def clean_up() -> None:
        if owns_folder:
            remove_if_unused(log_dir, created)

    start = time.time()
    last = None
    _stop_on_signals()
    try:
        print(f"{PROG}: {apply_threads(cfg, args.threads)}", flush=True)
        runner = make_runner(cfg, log_dir, verbose=args.verbose, config=config)
        if getattr(runner.alg, "amp", None) is not None:
            print(f"{PROG}: {runner.alg.amp.summary}", flush=True)
        if args.resume:
            try:
                runner.load(args.resume, resume=True)
            except ValueError as error:
                network = [o for o in config["overrides"]
                           if o.startswith(("runner.actor", "runner.critic", "runner.obs_groups"))]
                if not network:
                    raise
                raise ValueError(f"{' '.join(network)} does not fit the networks saved in {args.resume} ({error}); "
                                 "a resumed run keeps the checkpoint's networks: drop the override, or start a new "
                                 "run with --task.") from None
        elif args.init_from:
            parts = {**INIT_FROM_PARTS, "amp": not args.fresh_discriminator}
            runner.load(args.init_from, load_cfg=parts, widen_critic=True)
            _continue_env_progress(runner, args.init_from)
        first = runner.current_learning_iteration
        last = first + cfg.runner.max_iterations - 1
        print(f"{PROG}: {cfg.name}, {cfg.num_envs} envs on {cfg.device}, iterations {first}-{last} -> {log_dir}",
              flush=True)
        runner.learn(cfg.runner.max_iterations)
    except TrainingInterrupted as stop:
        clean_up()
        print(f"\n{PROG}: interrupted; " + (f"saved {stop.checkpoint}" if stop.checkpoint else "nothing to save."))
        if stop.checkpoint and checkpoints_in(log_dir):
            _summary(cfg, log_dir, stop.checkpoint, start, last=last)
        raise SystemExit(130) from None
    except KeyboardInterrupt:
        clean_up()
        raise SystemExit(f"\n{PROG}: interrupted before training started; nothing saved.") from None
    except (NonFiniteTraining, PhysicsOverflowStopped) as stop:
        clean_up()
        raise SystemExit(f"{PROG}: {stop}") from None
    except (ValueError, FileNotFoundError, FileExistsError, ImportError, DistributedSetupError) as error:
        clean_up()
        if args.verbose:
            raise
        raise SystemExit(f"{PROG}: {error}") from None
    except BaseException:
        clean_up()
        raise
    _summary(cfg, log_dir, checkpoints_in(log_dir)[-1], start)


def _continue_env_progress(runner, path: str) -> None:
    """--init-from: the env's training progress (the fall-recovery curriculum's assist level and action scale) that
    the networks were trained at, not its random streams: a fine-tuned getting-up policy must not restart at full
    assist and eta 1."""
    state = (load_checkpoint(path).get("training_state") or {}).get("env") or {}
    progress = {k: v for k, v in state.items()  # numbers only: per-env state (the toy's positions) is not progress
                if k not in ("generator", "rng") and isinstance(v, (int, float)) and not isinstance(v, bool)}
    if progress and hasattr(runner.env, "load_state_dict"):
        runner.env.load_state_dict(progress)
        print(f"{PROG}: the env continues the checkpoint's progress: "
              + ", ".join(f"{k} {v:g}" for k, v in progress.items()), flush=True)


def _stop_on_signals() -> None:
    """SIGTERM (``kill``, a cluster scheduler's warning) and SIGINT stop training as Ctrl-C does: the last finished
    iteration is saved. SIGINT is handled even when the shell started the run in the background with it ignored."""

    def interrupt(signum, frame):
        for number in (signal.SIGINT, signal.SIGTERM):  # a second Ctrl-C while saving must not cut the save short
            signal.signal(number, lambda *_: print(f"\n{PROG}: stopping, saving the last finished iteration...",
                                                   flush=True))
        raise KeyboardInterrupt

    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, interrupt)


def _summary(cfg, log_dir: str, checkpoint: str, start: float, last: int | None = None) -> None:
    """Where everything is and what to run next, with the real paths; ``last``: the iteration the run meant to end
    at (an interrupted run continues with what is left)."""
    q = shlex.quote
    names = ", ".join(os.path.basename(p) for p in checkpoints_in(log_dir))
    elapsed = datetime.timedelta(seconds=round(time.time() - start))
    lines = [
        f"{PROG}: done in {elapsed}. Checkpoints in {log_dir}: {names}",
        f"  TensorBoard:  tensorboard --logdir {q(log_dir)}",
        f"  export:       pchc-export-onnx {q(checkpoint)} -o {q(os.path.join(log_dir, 'policy.onnx'))}",
    ]
    if cfg.name in TASK_EVALUATION:
        lines.append(f"  evaluate:     pchc-eval {q(checkpoint)} --output {q(os.path.join(log_dir, 'eval'))}")
    more = cfg.runner.max_iterations
    name = os.path.basename(checkpoint)[6:-3]
    if last is not None and name.isdigit() and last > int(name):
        more = last - int(name)
    lines.append(f"  continue:     pchc-train --resume {q(checkpoint)} --max-iterations {more}")
    print("\n".join(lines))


def _task_help(argv: list[str]) -> str:
    """With ``--task T --help``: the task's full config, for the help's epilog."""
    if not {"-h", "--help"} & set(argv):
        return ""
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--task")
    known, _ = pre.parse_known_args(argv)
    if known.task not in TASKS:
        return "Give --task TASK with --help to list that task's config."

    return f"config of task {known.task} (set any with KEY=VALUE):\n" + format_config(task_config(known.task))


def _take_overrides_from_motion_files(args) -> None:
    """``--motion-files a.csv KEY=VALUE``: argparse gives every word to --motion-files; a word shaped like an
    override (a dotted name, '=', no '/') is one."""
    if args.motion_files:
        words = args.motion_files
        args.motion_files = [w for w in words if not OVERRIDE_SHAPE.match(w)]
        args.overrides = [w for w in words if OVERRIDE_SHAPE.match(w)] + list(args.overrides)


def _show(value) -> str:
    return json.dumps(value, default=str)


if __name__ == "__main__":
    main()
