"""Training output a person reads: one line per iteration instead of rsl-rl's 28-line block.

The scalars written to TensorBoard (or W&B, Neptune) are rsl-rl's own: this Logger lets rsl-rl's ``log`` do all the
writing and only decides what reaches the console. rsl-rl's full block is still printed with ``verbose``, without
its terminal colour codes so that it reads well in a log file.
"""

from __future__ import annotations

import contextlib
import datetime
import io
import re
import statistics
from collections.abc import Callable

import torch

from rsl_rl.utils.logger import Logger

ANSI_ESCAPE = re.compile(r"\x1b\[[0-9;]*m")
OBJECTIVE_PREFIX = "Episode_Objective/"
FALL_KEY = "Episode_Termination/fall"
ROUTING_PREFIX = "routing_mass"


class IterationLogger(Logger):
    """rsl-rl's Logger printing ``it 12/59 | reward ... | <objective> ... | falls ..% | steps/s | ETA``.

    ``guard(it, loss_dict)`` runs first at every iteration (the runner's non-finite check): it may raise to stop
    training before anything of that iteration is logged or saved. Per-critic diagnostics (``value_error/<group>``,
    ``advantage_std/<group>``: keys with a '/') are not losses: they go to ``Critic/<key>``, not ``Loss/<key>``; a
    mixture actor's ``routing_mass/expert_<j>`` (each expert's mean weight over the rollout) goes to
    ``Routing/expert_<j>``.
    """

    def __init__(self, *args, verbose: bool = False, guard: Callable[[int, dict], None] | None = None, **kwargs):
        super().__init__(*args, **kwargs)
        self.verbose = verbose
        self.guard = guard
        self.iteration_times: list[float] = []
        self.physics_stats: dict[str, float] = {}
        """The env's physics report of the last rollout (``env.physics_report()``), written as ``Physics/<key>``."""
        self._finished_steps: list[tuple[torch.Tensor, list[torch.Tensor]]] = []
        """Per env step since the last flush: which envs finished an episode, and the running sums at that step."""

    def process_env_step(self, rewards: torch.Tensor, dones: torch.Tensor, extras: dict,
                         intrinsic_rewards: torch.Tensor | None = None) -> None:
        """rsl-rl's book-keeping of finished episodes, kept on the device: rsl-rl finds the finished envs and copies
        their sums to the host at every step (three host syncs); here each step records its finished-episode
        values and mask, and ``flush_finished_episodes`` moves them to the buffers once per iteration, in the same
        order (step by step, env by env)."""
        if self.writer is None:
            return
        if "episode" in extras:
            self.ep_extras.append(extras["episode"])
        elif "log" in extras:
            self.ep_extras.append(extras["log"])
        sums = [self.cur_reward_sum, self.cur_episode_length]
        if intrinsic_rewards is not None:
            self.cur_ereward_sum += rewards
            self.cur_ireward_sum += intrinsic_rewards
            self.cur_reward_sum += rewards + intrinsic_rewards
            sums += [self.cur_ereward_sum, self.cur_ireward_sum]
        else:
            self.cur_reward_sum += rewards
        self.cur_episode_length += 1
        finished = dones.reshape(-1) > 0
        self._finished_steps.append((finished, [s.clone() for s in sums]))
        for s in sums:
            s.masked_fill_(finished, 0)

    def flush_finished_episodes(self) -> None:
        """Move the episodes that finished since the last flush into rsl-rl's reward and length buffers."""
        if not self._finished_steps:
            return
        finished = torch.stack([mask for mask, _ in self._finished_steps])  # [T, N]
        columns = zip(*(values for _, values in self._finished_steps))
        buffers = [self.rewbuffer, self.lenbuffer]
        if len(self._finished_steps[0][1]) == 4:
            buffers += [self.erewbuffer, self.irewbuffer]
        for buffer, column in zip(buffers, columns):
            buffer.extend(torch.stack(column)[finished].cpu().tolist())
        self._finished_steps.clear()

    def init_logging_writer(self) -> None:
        """rsl-rl's, without its 'Storing git diff' prints unless verbose."""
        with contextlib.redirect_stdout(io.StringIO()) if not self.verbose else contextlib.nullcontext():
            super().init_logging_writer()

    def log(self, it: int, start_it: int, total_it: int, collect_time: float, learn_time: float, loss_dict: dict,
            **kwargs) -> None:
        if self.guard is not None:
            self.guard(it, loss_dict)
        self.flush_finished_episodes()
        losses = {k: v for k, v in loss_dict.items() if "/" not in k}
        diagnostics = {k: v for k, v in loss_dict.items() if "/" in k}
        self._drop_undefined()
        line = self.summary_line(it, start_it, total_it, collect_time + learn_time)  # before rsl-rl clears extras
        block = io.StringIO()
        with contextlib.redirect_stdout(block):
            super().log(it=it, start_it=start_it, total_it=total_it, collect_time=collect_time,
                        learn_time=learn_time, loss_dict=losses, **kwargs)
        if self.writer is None:
            return
        for key, value in diagnostics.items():
            section, _, name = key.partition("/")
            tag = f"Routing/{name}" if section == ROUTING_PREFIX else f"Critic/{key}"
            self.writer.add_scalar(tag, value, it)
        for key, value in self.physics_stats.items():
            self.writer.add_scalar(f"Physics/{key}", value, it)
        print(line, flush=True)
        if self.verbose:
            print(ANSI_ESCAPE.sub("", block.getvalue()), flush=True)

    def summary_line(self, it: int, start_it: int, total_it: int, iteration_time: float) -> str:
        """Iteration, mean episode reward, each objective's mean episode sum, falls, throughput and ETA."""
        self.iteration_times.append(iteration_time)
        last = total_it - 1  # iterations count from 0, as the checkpoints model_<it>.pt do
        parts = [f"it {it:>{len(str(last))}}/{last}"]
        if self.rewbuffer:
            parts.append(f"reward {statistics.mean(self.rewbuffer):8.3f}")
        extras = self._episode_means()
        objectives = [f"{k[len(OBJECTIVE_PREFIX):]} {v:8.3f}" for k, v in extras.items() if k.startswith(OBJECTIVE_PREFIX)]
        if objectives:
            parts.append("  ".join(objectives))
        if FALL_KEY in extras:
            parts.append(f"falls {100 * extras[FALL_KEY]:3.0f}%")
        steps = self.cfg["num_steps_per_env"] * self.num_envs * self.gpu_world_size
        parts.append(f"{steps / max(iteration_time, 1e-9):,.0f} steps/s")
        remaining = total_it - 1 - it
        if len(self.iteration_times) > 1 and remaining > 0:
            # the first iteration includes start-up costs: leave it out of the estimate
            per_iteration = statistics.median(self.iteration_times[1:][-10:])
            parts.append(f"ETA {datetime.timedelta(seconds=round(per_iteration * remaining))}")
        return " | ".join(parts)

    def _drop_undefined(self) -> None:
        """Leave NaN out of the env's per-episode values (a metric an episode did not define, e.g. the deviation of
        an episode without a push) before rsl-rl averages them; done once per iteration, so the env's steps never
        wait on the device to find them."""
        for extras in self.ep_extras:
            for key, value in list(extras.items()):
                if isinstance(value, torch.Tensor) and value.is_floating_point():
                    flat = value.reshape(-1)
                    kept = flat[~flat.isnan()]
                    if len(kept):
                        extras[key] = kept
                    else:
                        del extras[key]

    def _episode_means(self) -> dict[str, float]:
        """Mean over this iteration's finished episodes of each scalar the env logged under extras['log'] (as
        rsl-rl's Logger takes it: every logged value counts once, a step's vector of episodes value by value)."""
        values: dict[str, list[torch.Tensor]] = {}
        for extras in self.ep_extras:
            for key, value in extras.items():
                try:
                    values.setdefault(key, []).append(torch.as_tensor(value, dtype=torch.float32).reshape(-1).cpu())
                except (TypeError, ValueError, RuntimeError):
                    continue
        return {k: float(torch.cat(v).mean()) for k, v in values.items() if v and sum(len(t) for t in v)}
