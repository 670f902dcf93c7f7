"""The progress bar of a run or a worker (tqdm on a terminal, nothing in logs)."""

from __future__ import annotations

import sys
import time

__all__ = ["Progress", "NOTE_EVERY"]

#: Seconds between two computations of the bar's note (the best value so far): the note is
#: computed from every record of the run, so computing it for every design made a study of n
#: designs read n^2 / 2 records (0.4 s of a 700-design structure study).
NOTE_EVERY = 0.5


class Progress:
    def __init__(self, total, enabled, desc, initial=0):
        self.bar = None
        self._noted = -float("inf")
        self._pending = None  # the note not shown yet (computed at close)
        if enabled:
            try:
                from tqdm import tqdm  # lazy: tqdm is optional

                # disable=None: a bar on a terminal, nothing in logs (the summary follows).
                self.bar = tqdm(total=total, desc=desc, unit="design", file=sys.stderr, dynamic_ncols=True,
                                disable=None, mininterval=0.5, initial=initial)
            except ImportError:
                self.bar = None

    def update(self, rec=None, best=None, n: int = 1):
        """Count ``n`` designs; ``best``: the note beside the bar, a string or a function giving
        it, computed only for a bar that is shown and at most every :data:`NOTE_EVERY` s (the
        last one when the bar closes)."""
        if self.bar is None:
            return
        self.bar.update(n)
        if best is None or getattr(self.bar, "disable", False):
            return
        now = time.monotonic()
        if now - self._noted < NOTE_EVERY:
            self._pending = best
            return
        self._noted, self._pending = now, None
        self.bar.set_postfix_str(best() if callable(best) else best, refresh=False)

    def set_count(self, n: int):
        """Show ``n`` designs done (counted in the storage, other workers included)."""
        if self.bar is not None and n != self.bar.n:
            self.bar.n = n
            self.bar.refresh()

    def close(self):
        if self.bar is not None:
            if self._pending is not None:
                best, self._pending = self._pending, None
                self.bar.set_postfix_str(best() if callable(best) else best, refresh=False)
            self.bar.close()
