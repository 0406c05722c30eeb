"""pchc-eval: the paper's evaluation of one or more checkpoints at fixed preferences."""

from __future__ import annotations

import argparse
import os
import re
import signal

from pchc_rsl.cli import arguments
from pchc_rsl.evaluation.presets import TASK_EVALUATION, evenly_spaced_preferences

PROG = "pchc-eval"


def build_parser() -> argparse.ArgumentParser:
    parser = arguments.Parser(
        prog=PROG,
        description="Evaluate checkpoints at fixed preferences under the task's evaluation preset (G1: no "
        "randomisation, no noise, the paper's pushes; toy: undiscounted returns of each goal); write results.json, "
        "table.md, pareto.png (and energy_curve.png for fall recovery, switching.png with --switch). A checkpoint "
        "trained with --fixed-preference is evaluated at that preference only: one point beside the fronts.",
    )
    parser.add_argument("checkpoints", nargs="+", metavar="CKPT [KEY=VALUE ...]",
                        help="checkpoints, then any config overrides applied after the evaluation preset, as on "
                        "pchc-train (e.g. env.action_delay_s=0.02,0.02 env.push.velocity=1.5,1.5)")
    parser.add_argument("--preferences", type=arguments.at_least_two, default=5,
                        help="evenly spaced preferences from (1,0) to (0,1) (default 5)")
    parser.add_argument("--preference", action="append", type=arguments.preference, metavar="L1,L2",
                        help="explicit preference(s) instead; repeatable")
    parser.add_argument("--num-envs", type=arguments.positive_int, default=64,
                        help="parallel envs (default 64: with --episodes 2, 128 episodes per preference, a few "
                             "minutes on 2 CPU cores; the paper uses 1000 envs)")
    parser.add_argument("--episodes", type=arguments.positive_int, default=2,
                        help="episodes per env and preference (default 2)")
    parser.add_argument("--seed", type=arguments.seed, default=0,
                        help="seed of the evaluation envs (initial states, push times and directions; default 0)")
    parser.add_argument("--device", default="cpu", help="torch device of the policy and Warp physics (default cpu)")
    parser.add_argument("--robustness", action="store_true",
                        help="instead of the tables: every preference under the deployment shifts (latency, "
                        "physics, friction, mass, actuator strength, noise, commands, push sweep); writes "
                        "robustness.json, robustness.md, robustness.png")
    parser.add_argument("--condition", action="append", metavar="NAME",
                        help="with --robustness: only these conditions (repeatable; names as in robustness.md)")
    parser.add_argument("--push-presets", nargs="+", metavar="NAME",
                        help="push presets in place of the task's (mild, strong), e.g. mild-v1 strong-v1 (the "
                        "presets before the calibration); the table keeps its mild and strong columns")
    parser.add_argument("--force", action="store_true", help="write into an --output folder that holds results")
    parser.add_argument("--episode-length", type=arguments.positive_float, help="override the episode length (s)")
    parser.add_argument("--switch", action="store_true", help="also switch lambda (0,1) -> (1,0) mid-episode (G1)")
    parser.add_argument("--output", default="eval", help="folder for the results (default: eval)")
    parser.add_argument("--video", action="store_true", help="also write a video per checkpoint (see pchc-play)")
    parser.add_argument("-v", "--verbose", action="store_true", help="print the models and error tracebacks")
    return parser


OVERRIDE_SHAPE = re.compile(r"^[A-Za-z_][\w.]*=")


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_intermixed_args(argv)  # KEY=VALUE words may follow the options
    args.overrides = [word for word in args.checkpoints if OVERRIDE_SHAPE.match(word)]
    args.checkpoints = [word for word in args.checkpoints if not OVERRIDE_SHAPE.match(word)]
    if not args.checkpoints:
        raise SystemExit(f"{PROG}: give a checkpoint before the KEY=VALUE overrides.")
    if args.video and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        os.environ.setdefault("MUJOCO_GL", "egl")  # headless rendering; read when mujoco is first imported
    signal.signal(signal.SIGTERM, _interrupt)  # kill: stop as Ctrl-C does, the finished part stays written
    try:
        task, saved, preferences = check_inputs(args)
        if args.robustness:
            return robustness(args, saved, preferences)
        from pchc_rsl.evaluation import evaluate_checkpoint, write_outputs

        videos = []
        if args.video:
            from pchc_rsl.envs.g1.render import RenderingUnavailable
            from pchc_rsl.viewers.recording import write_eval_videos

            os.makedirs(args.output, exist_ok=True)
            try:
                videos = write_eval_videos(args.checkpoints, preferences, args)
            except RenderingUnavailable as error:
                raise SystemExit(f"{PROG} --video: {error}") from None
        results, curves, switching = [], {}, None
        evaluation = TASK_EVALUATION[task]

        def write_partial(result, curve, switch):
            """What finished so far, written (marked partial) so that an interrupt loses only the running part."""
            curves[result["name"]] = curve
            write_outputs([*results, result], evaluation, curves, switching or switch, args.output, args.seed,
                          args.overrides, partial=True)
            written_partial.append(result["name"])

        for index, path in enumerate(args.checkpoints):
            result, curve, switch = evaluate_checkpoint(
                path, saved[path], preferences, num_envs=args.num_envs, episodes=args.episodes, seed=args.seed,
                episode_length=args.episode_length, switch=args.switch, overrides=args.overrides,
                verbose=args.verbose, device=args.device, presets=args.push_presets, on_preset=write_partial)
            results.append(result)
            curves[result["name"]] = curve
            switching = switching or switch
            if index < len(args.checkpoints) - 1:
                write_partial(result, curve, switch)
    except KeyboardInterrupt:
        raise SystemExit(f"\n{PROG}: interrupted; " + (
            f"the part that finished is in {args.output} (results.json and table.md marked partial)"
            if written_partial else "nothing had finished, nothing written") + ".") from None
    except (ValueError, FileNotFoundError) as error:
        if args.verbose:
            raise
        raise SystemExit(f"{PROG}: {error}") from None
    from pchc_rsl.evaluation import markdown_table

    written = write_outputs(results, evaluation, curves, switching, args.output, args.seed, args.overrides) + videos
    print(markdown_table(results, evaluation))
    for result in results:
        f = result["front"]
        print(f"{result['name']}: hypervolume {f['hypervolume']:.4g} (reference point {f['reference_point']}), "
              f"sparsity {f['sparsity']:.4g}, {f['num_points']} non-dominated points")
    if switching is not None:
        settle = switching["settle_time_s"]
        print(f"switch (0, 1) -> (1, 0) at {switching['switch_step'] * switching['dt']:.1f} s: {switching['falls']} "
              f"falls, settled after " + ("n/a" if settle != settle else f"{settle:.2f} s"))
    print(f"{PROG}: wrote " + ", ".join(written))


def _interrupt(signum, frame):
    raise KeyboardInterrupt


written_partial: list[str] = []
"""Names whose finished part was written marked partial in this process (what an interrupt leaves behind)."""


def robustness(args, saved: dict, preferences) -> None:
    """--robustness: each checkpoint under the deployment shifts, into OUTPUT (OUTPUT/NAME with several); each
    condition's results are written as it finishes (marked partial until the last), so an interrupt keeps them."""
    from pchc_rsl.evaluation import default_conditions, run_robustness, write_robustness

    for path, config in saved.items():
        conditions = default_conditions(config["task"])
        if args.condition:
            known = {c.name: c for c in conditions}
            unknown = [name for name in args.condition if name not in known]
            if unknown:
                raise SystemExit(f"{PROG}: unknown condition(s) {unknown}; the conditions of task "
                                 f"'{config['task']}' are: " + "; ".join(known))
            conditions = [known[name] for name in args.condition]
        output = args.output if len(saved) == 1 else os.path.join(args.output, os.path.basename(path))

        def write_partial(report, output=output):
            write_robustness(report, output)
            written_partial.append(output)

        try:
            report = run_robustness(path, config, preferences, conditions, args.num_envs, args.episodes, args.seed,
                                    args.overrides, args.verbose, args.device, on_condition=write_partial)
        except KeyboardInterrupt:
            raise SystemExit(f"\n{PROG}: interrupted; " + (
                f"the conditions that finished are in {output} (robustness.json and .md marked partial)"
                if written_partial else "no condition had finished, nothing written") + ".") from None
        written = write_robustness(report, output)
        with open(written[1]) as f:
            print(f.read())
        print(f"{PROG}: wrote " + ", ".join(written))


def check_inputs(args) -> tuple[str, dict, list[tuple[float, ...]]]:
    """Everything that can be refused before evaluating: unreadable checkpoints, tasks without an evaluation or
    differing between checkpoints, preferences off the simplex, --switch on a task without it, a file as --output.
    Returns the task, each checkpoint's saved config and the preferences."""
    from pchc_rsl.preference import validate_preference
    from pchc_rsl.runners import load_checkpoint
    from pchc_rsl.training.build import saved_config

    if os.path.exists(args.output) and not os.path.isdir(args.output):
        raise ValueError(f"--output {args.output} is a file; give a folder.")
    if os.path.isdir(args.output) and os.listdir(args.output) and not args.force:
        raise ValueError(f"--output {args.output} already holds files; give a new folder, or --force to write "
                         "over them.")
    saved = {}
    for path in args.checkpoints:
        config = saved_config(path, load_checkpoint(path))
        if config["task"] not in TASK_EVALUATION:
            raise ValueError(f"{path} is for task '{config['task']}'; evaluation is defined for "
                             f"{', '.join(sorted(TASK_EVALUATION))}.")
        saved[path] = config
    evaluations = {id(TASK_EVALUATION[c["task"]]) for c in saved.values()}
    if len(evaluations) != 1:
        raise ValueError("checkpoints of different tasks " + str(sorted({c["task"] for c in saved.values()}))
                         + " cannot share one table; evaluate them separately.")
    task = next(iter(saved.values()))["task"]
    unknown = [name for name in args.push_presets or [] if name not in TASK_EVALUATION[task].pushes]
    if unknown:
        known = ", ".join(TASK_EVALUATION[task].pushes) or "none"
        raise ValueError(f"--push-presets {' '.join(unknown)}: task '{task}' has the push presets {known}.")
    if args.switch and TASK_EVALUATION[task].episode_returns:
        raise ValueError(f"--switch measures falls and settling of the G1 tasks; task '{task}' has no such metrics.")
    if args.episode_length is not None and TASK_EVALUATION[task].episode_returns:
        raise ValueError(f"task '{task}' is evaluated on the episodes it was trained on; drop --episode-length.")
    num_objectives = len(next(iter(saved.values()))["env"]["objective_names"])
    if args.preference:
        preferences = []
        for p in args.preference:
            try:
                preferences.append(tuple(validate_preference(p, num_objectives).tolist()))
            except ValueError as error:
                raise ValueError(f"--preference {','.join(f'{x:g}' for x in p)}: {error}") from None
    else:
        preferences = evenly_spaced_preferences(args.preferences)
    return task, saved, preferences


if __name__ == "__main__":
    main()
