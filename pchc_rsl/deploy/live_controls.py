"""What an operator moves while the policy runs: lambda along the simplex and the velocity command (forward,
lateral, yaw rate), from the keyboard, the G1 remote (buttons as edges, so a held button acts once; sticks as
unitree_rl_gym's deploy_real maps them) or the browser console."""

from __future__ import annotations

import queue
import sys
import threading

import numpy as np

from pchc_rsl.export.metadata import COMMAND_COMPONENTS

PREFERENCE_STEP = 0.1
SPEED_STEP = 0.1
"""m/s per key press (forward, lateral)."""
YAW_STEP = 0.1
"""rad/s per key press."""
SUM_TOLERANCE = 1e-5  # pchc_rsl.preference.SUM_TOLERANCE (that module imports torch; this one must not)

COMMAND_WORDS = {"lin_vel_x": ("forward", "m/s", "w / x", "the left stick forward/back"),
                 "lin_vel_y": ("lateral", "m/s", "a / d", "the left stick sideways"),
                 "ang_vel_z": ("yaw rate", "rad/s", "q / e", "the right stick sideways")}
FALLBACK_COMMAND_RANGES = {"lin_vel_x": (0.0, 1.0), "lin_vel_y": (0.0, 0.0), "ang_vel_z": (0.0, 0.0)}
"""For a policy file that observes a command but carries no ranges (exported before the metadata held them): the
forward-only walking task's ranges."""
STICK_DEAD_BAND = 0.1
"""|stick| below this is centre: a released stick rests slightly off zero."""

KEY_HELP = ("keys: s start (ramp to the default pose), p policy, space damping, Q quit (damps, then exits); [ ] lambda "
            "towards objective 1 / 2 (more objectives: 1-9 picks one, + - moves it); w x forward, a d lateral "
            "+/- 0.1 m/s, q e yaw rate +/- 0.1 rad/s, z stop")
REMOTE_HELP = ("remote: start = ramp, A = policy, select or B = damping; L1 / R1 lambda towards objective 1 / 2; "
               "left stick forward/back and sideways, right stick sideways = yaw rate; up / down forward +/- 0.1")


def check_preference(values, names: list[str]) -> np.ndarray:
    """lambda on the simplex over the objectives ``names``, or ValueError saying what is wrong."""
    value = np.asarray(values, dtype=np.float64).reshape(-1)
    m = len(names)
    if value.shape[0] != m:
        raise ValueError(f"the policy weighs {m} objectives ({', '.join(names)}); --preference gives "
                         f"{value.shape[0]} weights: give {m}, e.g. {','.join(['%.2g' % (1 / m)] * m)}")
    if not np.isfinite(value).all() or (value < 0).any():
        raise ValueError(f"preference weights must be finite and >= 0, got {','.join('%g' % v for v in value)}")
    if abs(value.sum() - 1.0) > SUM_TOLERANCE:
        raise ValueError(f"preference weights must sum to 1, got a sum of {value.sum():g} for "
                         f"{','.join('%g' % v for v in value)}; divide by the sum to normalise")
    return value


class Preference:
    """lambda on the simplex, moved in steps; for two objectives a step moves weight from one to the other."""

    def __init__(self, initial, objective_names: list[str]) -> None:
        self.names = objective_names
        self.value = check_preference(initial, objective_names)
        self.selected = 0

    def towards(self, k: int, delta: float = PREFERENCE_STEP) -> None:
        """Raise objective k's weight by ``delta`` (lower it for a negative delta), the others scaled to keep the
        sum at 1."""
        value = self.value.copy()
        value[k] = float(np.clip(value[k] + delta, 0.0, 1.0))
        rest = np.delete(np.arange(len(value)), k)
        others = value[rest].sum()
        value[rest] = (value[rest] / others if others > 0 else 1.0 / len(rest)) * (1.0 - value[k])
        self.value = value

    def __str__(self) -> str:
        return "lambda = (" + ", ".join(f"{n} {v:.2f}" for n, v in zip(self.names, self.value)) + ")"


def command_ranges_of(meta: dict) -> tuple[dict | None, str]:
    """(ranges by component, a note for the operator) from a policy's metadata: None for a policy without a
    velocity command; the fallback, with a note saying so, for a file that has a command but no ranges."""
    if not any(name == "velocity_command" for name, _ in meta["observation"]["frame"]):
        return None, ""
    ranges = meta.get("command_ranges")
    if not ranges:
        shown = ", ".join(f"{COMMAND_WORDS[k][0]} {lo:g}..{hi:g}" for k, (lo, hi) in FALLBACK_COMMAND_RANGES.items())
        return dict(FALLBACK_COMMAND_RANGES), (f"the policy file carries no command ranges (exported before they "
                                               f"were recorded); using {shown}. Re-export it to steer it as trained.")
    unknown = set(ranges) - set(COMMAND_COMPONENTS)
    if unknown:
        raise ValueError(f"the policy's command has components {sorted(unknown)} unknown to this pchc-deploy "
                         f"(it knows {', '.join(COMMAND_COMPONENTS)}); update pchc-rsl.")
    return {k: tuple(float(x) for x in ranges.get(k, (0.0, 0.0))) for k in COMMAND_COMPONENTS}, ""


class Command:
    """The walking command (forward, lateral, yaw rate), each component clipped to the range the policy trained it
    in. A component trained at (0, 0) is no command of this policy: setting it is refused, in one line, once."""

    def __init__(self, ranges: dict | None, initial=(0.0, 0.0, 0.0)) -> None:
        self.ranges = ranges
        self.value = np.zeros(3)
        self.low = np.array([ranges[k][0] for k in COMMAND_COMPONENTS]) if ranges else np.zeros(3)
        self.high = np.array([ranges[k][1] for k in COMMAND_COMPONENTS]) if ranges else np.zeros(3)
        self._refused: set[int] = set()
        initial = np.asarray(initial, float)
        for k, v in enumerate(initial):
            if v != 0.0 and not self.trained(k):
                name, unit, *_ = COMMAND_WORDS[COMMAND_COMPONENTS[k]]
                raise ValueError(f"--command's {name} {v:g} {unit}: {self.refusal(k)}; give 0 there")
            if not self.low[k] - 1e-9 <= v <= self.high[k] + 1e-9:
                name, unit, *_ = COMMAND_WORDS[COMMAND_COMPONENTS[k]]
                raise ValueError(f"--command's {name} {v:g} {unit} is outside the range the policy was trained in, "
                                 f"{self.low[k]:g}..{self.high[k]:g} {unit}")
        self.value[:] = initial

    def trained(self, k: int) -> bool:
        return bool(self.high[k] > self.low[k])

    def refusal(self, k: int) -> str:
        if self.ranges is None:
            return "this policy takes no velocity command (its observation has none); the steering keys, sticks and --command do nothing"
        key = COMMAND_COMPONENTS[k]
        name, _, keys, stick = COMMAND_WORDS[key]
        return (f"this policy takes no {name} command (trained with {key} {self.low[k]:g}..{self.high[k]:g}); "
                f"{keys} and {stick} do nothing")

    def set(self, k: int, value: float) -> str:
        """Set component k (clipped to its range); '' or, the first time only, why it was refused."""
        if not self.trained(k):
            tag = k if self.ranges is not None else -1  # without a command at all: one line for every component
            if value == 0.0 or tag in self._refused:
                return ""
            self._refused.add(tag)
            return self.refusal(k)
        self.value[k] = float(np.clip(round(value, 3), self.low[k], self.high[k]))
        return ""

    def change(self, k: int, delta: float) -> str:
        return self.set(k, self.value[k] + delta)

    def stop(self) -> None:
        self.value[:] = np.clip(0.0, self.low, self.high)

    def from_sticks(self, forward: float, lateral: float, yaw: float) -> list[str]:
        """Stick deflections in [-1, 1] (dead band removed) scaled to each range: full forward is the range's top,
        full back its bottom. Returns refusals (each once)."""
        notes = []
        for k, s in enumerate((forward, lateral, yaw)):
            note = self.set(k, s * self.high[k] if s > 0 else -s * self.low[k]) if self.trained(k) else self.set(k, s)
            notes += [note] if note else []
        return notes

    def __str__(self) -> str:
        if self.ranges is None:
            return "no command"
        parts = [f"{COMMAND_WORDS[k][0]} {self.value[i]:+.2f} {COMMAND_WORDS[k][1]}"
                 for i, k in enumerate(COMMAND_COMPONENTS) if self.trained(i)]
        return "command " + ", ".join(parts)


def stick_command(lx: float, ly: float, rx: float, dead_band: float = STICK_DEAD_BAND) -> tuple[float, float, float]:
    """unitree_rl_gym deploy_real's map (cmd = ly, -lx, -rx: left stick forward and sideways, right stick sideways
    for the yaw rate; pushing right is a negative lateral speed and yaw rate) with a dead band: each axis is 0
    inside it and rescaled outside it so that the command starts from 0 at its edge."""
    def axis(v: float) -> float:
        v = float(np.clip(v, -1.0, 1.0))
        return 0.0 if abs(v) < dead_band else np.sign(v) * (abs(v) - dead_band) / (1.0 - dead_band)

    return axis(ly), -axis(lx), -axis(rx)


class KeyReader:
    """Single key presses from a terminal, read on a thread into a queue; inactive when stdin is no terminal."""

    def __init__(self) -> None:
        self.events: queue.Queue[str] = queue.Queue()
        self._saved = None
        if not sys.stdin.isatty():
            return
        import termios  # POSIX only, read where a terminal is: the module's parsers load on any OS
        import tty

        self._saved = termios.tcgetattr(sys.stdin)
        tty.setcbreak(sys.stdin.fileno())
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        while True:
            key = sys.stdin.read(1)
            if not key:
                return
            self.events.put(key)

    @property
    def active(self) -> bool:
        """Reading a terminal (stdin is one)."""
        return self._saved is not None

    def pending(self) -> list[str]:
        keys = []
        while not self.events.empty():
            keys.append(self.events.get_nowait())
        return keys

    def close(self) -> None:
        if self._saved is not None:
            import termios

            termios.tcsetattr(sys.stdin, termios.TCSADRAIN, self._saved)
            self._saved = None


class RemoteEdges:
    """Buttons that went down since the last call."""

    def __init__(self) -> None:
        self._held: frozenset = frozenset()

    def pressed(self, buttons: frozenset) -> frozenset:
        new = buttons - self._held
        self._held = buttons
        return new
