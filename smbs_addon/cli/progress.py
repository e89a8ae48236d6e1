"""The command line's progress on stderr: a line that rewrites itself on a terminal, a line per stage
in logs (render farms)."""
from __future__ import annotations

import sys
import time

from .report import duration

SLOW_BAKE_S = 24 * 3600  # a bake whose measured rate says it takes longer is warned of, once


class Progress:
    """The bake's progress on stderr: a line that rewrites itself on a terminal, a line per stage in
    logs (render farms); with the time it will take at its rate so far, and a warning, once, where
    that is more than SLOW_BAKE_S."""

    def __init__(self, quiet: bool, tty: bool):
        self.quiet, self.tty = quiet, tty
        self.last = ""
        self.t0 = time.perf_counter()
        self.warned = False

    def left(self, frac: float) -> float | None:
        spent = time.perf_counter() - self.t0
        if frac <= 0 or spent < 2.0:
            return None
        return spent * (1.0 - frac) / frac

    def __call__(self, frac, msg):
        if self.quiet:
            return
        left = self.left(frac)
        if left is not None and left > SLOW_BAKE_S and not self.warned:
            self.warned = True
            print(f"{chr(10) if self.tty else ''}warning: at its rate so far this bake takes about {_long(left)} "
                  f"more; fewer samples (--spp) or a --time or --noise rule end it sooner", file=sys.stderr,
                  flush=True)
        if self.tty:
            eta = f" (about {_long(left)} left)" if left is not None and frac < 1 else ""
            print(f"\r{frac:6.1%} {msg}{eta}\033[K", end="", file=sys.stderr, flush=True)
        elif msg != self.last:
            print(f"{frac:6.1%} {msg}", file=sys.stderr, flush=True)
            self.last = msg


def _long(s: float) -> str:
    """A duration from seconds to ages."""
    year = 365.25 * 86400
    if s < 2 * 86400:
        return duration(s)
    if s < year:
        return f"{s / 86400:.0f} days"
    return f"{s / year:.3g} years"
