"""A walking command scripted over time, for ``pchc-deploy --command-sequence FILE``: one row per line,

    seconds  forward  lateral  yaw_rate      # m/s, m/s, rad/s; columns apart by spaces or commas

each row's command held from its start (seconds since the policy started) until the next row's, the last until the
run ends; ``#`` starts a comment. The whole file is checked against the policy's trained command ranges before
anything moves, so that a typo stops the deploy at its start, not halfway through a walk."""

from __future__ import annotations

import math
from dataclasses import dataclass

from pchc_rsl.deploy.live_controls import COMMAND_COMPONENTS, COMMAND_WORDS

COLUMNS = "seconds forward lateral yaw_rate"


@dataclass(frozen=True)
class CommandRow:
    start: float
    """Seconds since the policy started."""
    command: tuple[float, float, float]
    """Forward (m/s), lateral (m/s, left positive), yaw rate (rad/s, left positive)."""
    line: int


class CommandSequence:
    """Rows in time order, the first at 0 s."""

    def __init__(self, rows: list[CommandRow], path: str) -> None:
        self.rows, self.path = rows, path

    def at(self, t: float) -> CommandRow:
        """The row in force ``t`` seconds after the policy started."""
        current = self.rows[0]
        for row in self.rows[1:]:
            if row.start > t + 1e-9:
                break
            current = row
        return current

    def __str__(self) -> str:
        return f"{self.path} ({len(self.rows)} rows over {self.rows[-1].start:g} s, the last held to the end)"


def read_command_sequence(path: str, ranges: dict | None) -> CommandSequence:
    """The sequence in ``path``, every row checked against ``ranges`` (component -> (low, high), as the policy's
    metadata gives them; None for a policy without a velocity command). ValueError naming FILE:LINE otherwise."""
    if ranges is None:
        raise ValueError(f"{path}: this policy takes no velocity command (its observation has none); "
                         "--command-sequence has nothing to steer")
    try:
        with open(path) as f:
            lines = f.read().splitlines()
    except OSError as error:
        raise ValueError(f"--command-sequence {path}: {error.strerror or error}") from None
    rows: list[CommandRow] = []
    for number, text in enumerate(lines, start=1):
        words = text.split("#", 1)[0].replace(",", " ").split()
        if not words:
            continue
        where = f"{path}:{number}"
        try:
            values = [float(w) for w in words]
        except ValueError:
            values = []
        if len(values) != 4 or not all(math.isfinite(v) for v in values):
            raise ValueError(f"{where}: a row is four numbers ({COLUMNS}), got '{text.strip()}'")
        start, command = values[0], tuple(values[1:])
        if not rows and start != 0.0:
            raise ValueError(f"{where}: the first row starts when the policy does, at 0 s; got {start:g} s")
        if rows and start <= rows[-1].start:
            raise ValueError(f"{where}: rows go forward in time; {start:g} s does not come after the row at "
                             f"{rows[-1].start:g} s (line {rows[-1].line})")
        for k, value in enumerate(command):
            _check_component(where, COMMAND_COMPONENTS[k], value, ranges)
        rows.append(CommandRow(start, command, number))
    if not rows:
        raise ValueError(f"{path}: no command rows; write one per line: {COLUMNS} (e.g. '0 0.5 0 0')")
    return CommandSequence(rows, path)


def _check_component(where: str, key: str, value: float, ranges: dict) -> None:
    low, high = ranges[key]
    name, unit, *_ = COMMAND_WORDS[key]
    if high <= low and value != 0.0:
        raise ValueError(f"{where}: {name} {value:g} {unit}, but this policy takes no {name} command (trained with "
                         f"{key} {low:g}..{high:g}); give 0 there")
    if not low - 1e-9 <= value <= high + 1e-9:
        raise ValueError(f"{where}: {name} {value:g} {unit} is outside the range the policy was trained in, "
                         f"{low:g}..{high:g} {unit}")
