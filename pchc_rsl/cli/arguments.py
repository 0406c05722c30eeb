"""Command-line parsing shared by the CLIs: one-line errors, and numeric argument types that check their range.

Everything here runs before torch is imported, so a bad argument is refused at once.
"""

from __future__ import annotations

import argparse
import math
import re
import sys


NEGATIVE_VALUE = re.compile(r"^-\.?\d")


class Parser(argparse.ArgumentParser):
    """argparse, but an error is one line (``prog: error: ... (see --help)``) rather than usage + error, and an
    option's value may start with a minus (``--fixed-preference -0.5,1.5`` is read as the value, so that the
    simplex check can say what is wrong with it, instead of argparse's 'expected one argument')."""

    def parse_known_args(self, args=None, namespace=None):
        args = list(sys.argv[1:] if args is None else args)
        joined = []
        for word in args:
            previous = joined[-1] if joined else ""
            takes_value = previous.startswith("--") and "=" not in previous and self._takes_value(previous)
            if takes_value and NEGATIVE_VALUE.match(word):
                joined[-1] = f"{previous}={word}"
            else:
                joined.append(word)
        return super().parse_known_args(joined, namespace)

    def _takes_value(self, option: str) -> bool:
        action = self._option_string_actions.get(option)
        return action is not None and action.nargs is None and action.const is None and not isinstance(
            action, (argparse._StoreTrueAction, argparse._StoreFalseAction, argparse._HelpAction))

    def error(self, message: str):
        sys.stderr.write(f"{self.prog}: error: {message} (see {self.prog} --help)\n")
        raise SystemExit(2)


def positive_int(text: str) -> int:
    """An integer >= 1 (counts: envs, iterations, episodes)."""
    value = _int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, got {text}")
    return value


def at_least_two(text: str) -> int:
    value = _int(text)
    if value < 2:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 2 (both ends of the front), got {text}")
    return value


def seed(text: str) -> int:
    """A seed torch accepts: 0 <= seed < 2**63."""
    value = _int(text)
    if not 0 <= value < 2**63:
        raise argparse.ArgumentTypeError(f"must be a whole number in [0, 2**63), got {text}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0 (durations)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got '{text}'") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return value


def preference(text: str) -> list[float]:
    """``L1,L2[,...]``: comma-separated numbers (the simplex is checked once the task's objectives are known)."""
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be comma-separated numbers such as 0.5,0.5, got '{text}'") from None
    return values


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, got '{text}'") from None
