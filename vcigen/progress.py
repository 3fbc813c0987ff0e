"""A time-based progress bar on stderr for long runs (``simulate``, ``simulate_many``, ``sweep``, bench).

Nothing is shown for work that will take less than ``min_seconds``: the bar appears only once the
projected total time (elapsed time / fraction done) exceeds it, so short runs stay silent. On a
terminal it redraws one line (``\\r``) at most ``1 / REDRAW`` times a second, with the fraction done,
the elapsed time and an estimate of the time left; on a stream that is not a terminal (a log file,
a CI job) it writes a few plain lines at most: when it first appears, at each quarter, and at the end.

    with Progress(total=t_end - t0, desc="simulate") as bar:
        while ...:
            bar.update(t - t0)          # absolute progress, in the units of total
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

REDRAW = 0.2  # seconds between redraws on a terminal
WARMUP = 0.2  # seconds of work before the projection is trusted
WIDTH = 24  # characters of the bar


def format_seconds(s: float) -> str:
    """``"4.2s"``, ``"3m05s"``, ``"1h02m"``."""
    if s != s or s == float("inf"):
        return "?"
    if s < 60:
        return f"{s:.1f}s"
    if s < 3600:
        return f"{int(s // 60)}m{int(s % 60):02d}s"
    return f"{int(s // 3600)}h{int(s % 3600 // 60):02d}m"


class Progress:
    """A progress bar over ``total`` units of work (``update`` gives the units done so far)."""

    def __init__(
        self,
        total: float,
        desc: str = "",
        enabled: bool = True,
        min_seconds: float = 2.0,
        stream: TextIO | None = None,
    ) -> None:
        self.total = float(total)
        self.desc = desc
        self.enabled = bool(enabled) and self.total > 0
        self.min_seconds = float(min_seconds)
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = self.enabled and self.stream is not None  # no stderr (pythonw): nothing to draw on
        try:
            self.tty = bool(self.stream.isatty())
        except (AttributeError, ValueError):
            self.tty = False
        self.start = time.perf_counter()
        self.done = 0.0
        self.shown = False  # anything written yet
        self.lines = 0  # plain lines written (not a terminal)
        self._next_draw = 0.0  # perf_counter time of the next allowed redraw
        self._quarter = 0  # quarters already reported (not a terminal)
        self._closed = False

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def update(self, done: float) -> None:
        """Record that ``done`` units (absolute) of ``total`` are finished; redraw if it is time."""
        if not self.enabled or self._closed:
            return
        self.done = float(done)
        now = time.perf_counter()
        if now < self._next_draw:
            return
        elapsed = now - self.start
        if not self.shown and not self._long(elapsed):
            self._next_draw = now + 0.05  # look again soon, cheaply
            return
        if self.tty:
            self._draw(elapsed, end="")
            self._next_draw = now + REDRAW
        else:
            quarter = min(int(4 * self.done / self.total), 3)  # the end is close()'s line
            if not self.shown or quarter > self._quarter:
                self._quarter = quarter
                self._draw(elapsed, end="\n")
            self._next_draw = now + REDRAW
        self.shown = True

    def close(self) -> None:
        """Draw the final state (if the bar was shown) and end its line."""
        if self._closed:
            return
        self._closed = True
        if not (self.enabled and self.shown):
            return
        elapsed = time.perf_counter() - self.start
        self._draw(elapsed, end="\n", final=True)

    # -- internals ------------------------------------------------------------------
    def _long(self, elapsed: float) -> bool:
        """The work is (projected to be) longer than ``min_seconds``."""
        if elapsed >= self.min_seconds:
            return True
        if elapsed < WARMUP or self.done <= 0:
            return False
        return elapsed * self.total / self.done > self.min_seconds

    def _draw(self, elapsed: float, end: str, final: bool = False) -> None:
        frac = min(max(self.done / self.total, 0.0), 1.0)
        fill = int(round(frac * WIDTH))
        bar = "#" * fill + "." * (WIDTH - fill)
        if final:
            tail = f"{format_seconds(elapsed)}"
        else:
            eta = elapsed * (1.0 - frac) / frac if frac > 0 else float("inf")
            tail = f"{format_seconds(elapsed)} elapsed, ETA {format_seconds(eta)}"
        head = f"{self.desc}: " if self.desc else ""
        text = f"{head}[{bar}] {100 * frac:5.1f}% {tail}"
        if self.tty:
            text = "\r" + text + "\x1b[K"
        else:
            self.lines += 1
        self.stream.write(text + end)
        self.stream.flush()
