"""What an operator moves while the policy runs: lambda along the simplex and the velocity command, from the
keyboard or from the G1 remote's buttons (edges, so a held button acts once)."""

from __future__ import annotations

import queue
import sys
import threading

import numpy as np

from pchc_rsl.preference import validate_preference

PREFERENCE_STEP = 0.1
SPEED_STEP = 0.1
MAX_SPEED = 1.0

KEY_HELP = ("keys: s start (ramp to the default pose), p policy, d or space damping, q quit; [ ] lambda towards "
            "objective 1 / 2 (more objectives: 1-9 picks one, + - moves it); w x forward speed +/- 0.1, z stop")
REMOTE_HELP = ("remote: start = ramp, A = policy, select or B = damping; L1 / R1 lambda towards objective 1 / 2; "
               "up / down forward speed +/- 0.1")


class Preference:
    """lambda on the simplex, moved in steps; for two objectives a step moves weight from one to the other."""

    def __init__(self, initial, objective_names: list[str]) -> None:
        self.names = objective_names
        self.value = validate_preference(initial, len(objective_names)).double().numpy()
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


class Command:
    """The walking velocity command (forward speed only, as the walking task trains it)."""

    def __init__(self, forward: float = 0.0) -> None:
        self.value = np.zeros(3)
        self.set(forward)

    def set(self, forward: float) -> None:
        self.value[0] = float(np.clip(round(forward, 3), -MAX_SPEED, MAX_SPEED))

    def change(self, delta: float) -> None:
        self.set(self.value[0] + delta)

    def __str__(self) -> str:
        return f"command {self.value[0]:+.2f} m/s"


class KeyReader:
    """Single key presses from a terminal, read on a thread into a queue; inactive when stdin is no terminal."""

    def __init__(self) -> None:
        self.events: queue.Queue[str] = queue.Queue()
        self._saved = None
        if not sys.stdin.isatty():
            return
        import termios
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
