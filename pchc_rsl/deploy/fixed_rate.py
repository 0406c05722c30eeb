"""A loop that ticks on a fixed grid of a monotonic clock (tick k at start + k * period), so that the work's own
duration does not add up into drift as a sleep-after-the-work loop does; late ticks are counted, not bunched."""

from __future__ import annotations

import time


class FixedRateLoop:
    def __init__(self, period_s: float, clock=time.monotonic, sleep=time.sleep) -> None:
        self.period = period_s
        self.clock, self.sleep = clock, sleep
        self.next_tick: float | None = None
        self.ticks = self.overruns = 0
        self.worst_late_s = 0.0
        self.worst_late_at_s: float | None = None  # when the worst overrun happened, seconds after the first tick
        self.first_tick: float | None = None

    def wait(self) -> None:
        """Sleep until the next tick of the grid; a tick whose time has passed is an overrun, and the grid restarts
        from now when more than a whole period was lost (no burst of catch-up ticks)."""
        now = self.clock()
        if self.next_tick is None:
            self.next_tick = self.first_tick = now
        self.next_tick += self.period
        self.ticks += 1
        delay = self.next_tick - now
        if delay > 0:
            self.sleep(delay)
            return
        self.overruns += 1
        if -delay > self.worst_late_s:
            self.worst_late_s, self.worst_late_at_s = -delay, now - self.first_tick
        if -delay > self.period:
            self.next_tick = now

    def summary(self) -> dict:
        at = None if self.worst_late_at_s is None else round(self.worst_late_at_s, 3)
        return {"ticks": self.ticks, "overruns": self.overruns, "worst_late_ms": round(self.worst_late_s * 1e3, 2),
                "worst_late_at_s": at, "period_ms": round(self.period * 1e3, 3)}
