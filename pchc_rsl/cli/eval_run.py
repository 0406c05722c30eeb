"""What pchc-eval runs once its arguments are parsed (cli/eval.py) and MuJoCo's OpenGL backend is chosen: the
checks of the inputs against the checkpoints, the evaluation, the tables, figures and videos, or the deployment
shifts with --robustness; what finished is written even when interrupted."""

from __future__ import annotations

import os
import signal

from pchc_rsl.cli.eval import PROG
from pchc_rsl.envs.g1.render import RenderingUnavailable
from pchc_rsl.evaluation import (TASK_EVALUATION, default_conditions, evaluate_checkpoint, evenly_spaced_preferences,
                                 markdown_table, run_robustness, write_outputs, write_robustness)
from pchc_rsl.preference import validate_preference
from pchc_rsl.runners import load_checkpoint
from pchc_rsl.training.build import saved_config
from pchc_rsl.viewers.recording import write_eval_videos


def run(args) -> None:
    """The evaluation (or --robustness) of ``args.checkpoints`` with pchc-eval's parsed arguments."""
    signal.signal(signal.SIGTERM, _interrupt)  # kill: stop as Ctrl-C does, the finished part stays written
    try:
        task, saved, preferences = check_inputs(args)
        if args.robustness:
            return robustness(args, saved, preferences)
        videos = []
        if args.video:
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

