"""A progress line with the time left, for evaluations a user waits for (minutes on a busy CPU)."""

from __future__ import annotations

import datetime
import sys
import time


class Progress:
    """``label [#####.....] 120/600 steps, 1:05 left``: redrawn in place on a terminal; in a log file (not a
    terminal) one line per tenth of the work, so a user tailing it sees the estimate too."""

    def __init__(self, label: str, total: int, stream=None) -> None:
        self.label, self.total = label, max(int(total), 1)
        self.stream = stream or sys.stderr
        self.start = time.monotonic()
        self._last_tenth = 0
        self._tty = hasattr(self.stream, "isatty") and self.stream.isatty()

    def line(self, done: int, now: float | None = None) -> str:
        done = min(int(done), self.total)
        elapsed = (time.monotonic() if now is None else now) - self.start
        width = 30
        filled = int(width * done / self.total)
        left = "estimating" if done == 0 else (
            f"{datetime.timedelta(seconds=round(elapsed * (self.total - done) / done))} left")
        return f"{self.label} [{'#' * filled}{'.' * (width - filled)}] {done}/{self.total} steps, {left}"

    def update(self, done: int) -> None:
        if self._tty:
            self.stream.write("\r" + self.line(done))
            self.stream.flush()
            return
        tenth = int(10 * min(done, self.total) / self.total)
        if tenth > self._last_tenth:
            self._last_tenth = tenth
            self.stream.write(self.line(done) + "\n")
            self.stream.flush()

    def finish(self) -> None:
        elapsed = datetime.timedelta(seconds=round(time.monotonic() - self.start))
        text = f"{self.label}: done in {elapsed}"
        self.stream.write(("\r" + text + " " * 40 + "\n") if self._tty else text + "\n")
        self.stream.flush()
