"""pchc-runs: what to do with the runs pchc-train wrote: average checkpoints, plot training curves, release a
checkpoint as a policy."""

from __future__ import annotations

import argparse
import os

import torch

from pchc_rsl.cli import arguments
from pchc_rsl.evaluation.training_plots import plot_training, summary_table
from pchc_rsl.training.checkpoint_average import average_checkpoints
from pchc_rsl.training.release import release_policy
from pchc_rsl.utils.files import atomic_write

PROG = "pchc-runs"
RAW = argparse.RawDescriptionHelpFormatter


def build_parser() -> argparse.ArgumentParser:
    parser = arguments.Parser(prog=PROG, description="Work with the runs pchc-train wrote: average checkpoints of one "
                              "run, plot training curves, release a checkpoint as a policy (.pt and .onnx). "
                              "`pchc-runs COMMAND --help` for each.")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    verbose = arguments.Parser(add_help=False)
    verbose.add_argument("-v", "--verbose", action="store_true", help="tracebacks instead of one-line errors")

    def command(name: str, summary: str, description: str, examples: str) -> argparse.ArgumentParser:
        return commands.add_parser(name, parents=[verbose], formatter_class=RAW, help=summary,
                                   description=description, epilog=examples)

    average = command(
        "average", "average the networks of checkpoints of one run",
        "Average the actor and critics over checkpoints of one run (uniform weight averaging, as in\n"
        "SWA; docs/design.md, 'Checkpoint averaging'). Config, iteration and the rest are the newest checkpoint's;\n"
        "the optimizer state is dropped, so pchc-train --resume starts a fresh one.",
        "examples:\n"
        "  pchc-runs average RUN/model_{350,400,450,500,550}.pt --out avg.pt\n"
        "  pchc-runs average A.pt B.pt --weights 0.4 0.6 --actor-only --out mix.pt   # 0.6 of the way to B\n"
        "  pchc-runs average A.pt B.pt --weights 1 0 --expert-weights 0 0.25 0.5 0.75 1 --out mix.pt")
    average.add_argument("checkpoints", nargs="+", metavar="CKPT", help="two or more checkpoints of one run")
    average.add_argument("--out", required=True, help="the averaged checkpoint's path")
    average.add_argument("--weights", type=float, nargs="+", help="one per checkpoint, in the order given "
                         "(scaled to sum to 1; default: equal)")
    average.add_argument("--actor-only", action="store_true", help="average the actor only; the critics are the "
                         "newest checkpoint's (for critics of different shapes)")
    average.add_argument("--expert-weights", type=float, nargs="+", help="two checkpoints of a mixture actor: the "
                         "second one's share in each expert, in the order of mlp.positions (implies --actor-only)")

    curves = command(
        "curves", "plot training curves against env steps and hours",
        "Any logged scalar of runs against env steps and against wall-clock hours, from their\n"
        "TensorBoard events, and a table of where each curve ended. A resumed run: its folders joined by '+',\n"
        "steps and clock continuing; 'folder@N' keeps that folder's iterations up to N (a branch resumed from\n"
        "its model_N.pt while the folder's own run went on).",
        "example:\n"
        "  pchc-runs curves logs/run-a logs/run-b+logs/run-b-more \\\n"
        "      --tags Train/mean_reward Episode_Termination/fall --out curves.png")
    curves.add_argument("runs", nargs="+", metavar="RUN", help="run folders (a resumed run: folders joined by '+')")
    curves.add_argument("--tags", nargs="+", default=["Train/mean_reward", "Episode_Termination/fall"],
                        help="TensorBoard scalars, one row of panels each (default: Train/mean_reward "
                        "Episode_Termination/fall)")
    curves.add_argument("--labels", nargs="+", help="one label per run (default: the folder names)")
    curves.add_argument("--smooth", type=arguments.positive_int, default=20,
                        help="moving-average window in points (default 20)")
    curves.add_argument("--out", default="training_curves.png", help="the figure (default training_curves.png)")

    release = command(
        "release", "release a checkpoint as a small .pt and its .onnx",
        "Release a checkpoint: a small .pt (no optimizer, replay buffer or random streams; paths in\n"
        "its config cut to file names) and its ONNX export. pchc-eval, pchc-play and pchc-export-onnx read the .pt\n"
        "like any checkpoint; pchc-train --resume continues it with a fresh optimizer. Both files are written or\n"
        "neither; a release already there is only replaced with --force.",
        "example:\n"
        "  pchc-runs release logs/g1-walk/model_11999.pt --name g1_walk     # -> policies/g1_walk.pt, .onnx")
    release.add_argument("checkpoint", metavar="CKPT", help="a checkpoint written by pchc-train or pchc-runs average")
    release.add_argument("--name", required=True, help="file name without suffix, e.g. g1_walk")
    release.add_argument("--out", default="policies", help="folder (default: policies)")
    release.add_argument("--max-mb", type=arguments.positive_float, default=10.0,
                         help="refuse a file larger than this (default 10)")
    release.add_argument("--force", action="store_true", help="replace a release of this name")
    return parser


def average(args, prog: str) -> None:
    averaged = average_checkpoints(args.checkpoints, args.weights, args.actor_only, args.expert_weights)
    atomic_write(args.out, lambda tmp: torch.save(averaged, tmp))
    mean = "the weighted mean" if args.weights else "the mean"
    print(f"{prog}: wrote {args.out}, {mean} of {len(args.checkpoints)} checkpoints "
          f"(iterations {averaged['averaged_from'][0].rsplit('@', 1)[1]} to {averaged['iter']})")
    if args.expert_weights:
        positions = averaged["actor_state_dict"].get("mlp.positions")
        for share, position in zip(args.expert_weights, [] if positions is None else positions.tolist()):
            print(f"  expert at lambda = ({', '.join(f'{x:g}' for x in position)}): {share:g} of {args.checkpoints[1]}")


def curves(args, prog: str) -> None:
    labels = args.labels or [os.path.basename(spec.split("+")[0].rstrip("/")) for spec in args.runs]
    print(summary_table(plot_training(args.runs, args.tags, labels, args.out, args.smooth)))
    print(f"{prog}: wrote {args.out}")


def release(args, prog: str) -> None:
    for path, size in release_policy(args.checkpoint, args.name, args.out, args.max_mb, args.force):
        print(f"{prog}: wrote {path} ({size:.2f} MB)")


COMMANDS = {"average": average, "curves": curves, "release": release}


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    prog = f"{PROG} {args.command}"
    try:
        COMMANDS[args.command](args, prog)
    except (ValueError, FileNotFoundError, FileExistsError, RuntimeError) as error:
        if args.verbose:
            raise
        raise SystemExit(f"{prog}: {error}") from None


if __name__ == "__main__":
    main()
