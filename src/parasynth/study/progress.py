"""The progress bar of a run or a worker (tqdm on a terminal, nothing in logs)."""

from __future__ import annotations

import sys

__all__ = ["Progress"]


class Progress:
    def __init__(self, total, enabled, desc, initial=0):
        self.bar = None
        if enabled:
            try:
                from tqdm import tqdm  # lazy: tqdm is optional

                # disable=None: a bar on a terminal, nothing in logs (the summary follows).
                self.bar = tqdm(total=total, desc=desc, unit="design", file=sys.stderr, dynamic_ncols=True,
                                disable=None, mininterval=0.5, initial=initial)
            except ImportError:
                self.bar = None

    def update(self, rec=None, best=None, n: int = 1):
        if self.bar is not None:
            self.bar.update(n)
            if best is not None:
                self.bar.set_postfix_str(best, refresh=False)

    def set_count(self, n: int):
        """Show ``n`` designs done (counted in the storage, other workers included)."""
        if self.bar is not None and n != self.bar.n:
            self.bar.n = n
            self.bar.refresh()

    def close(self):
        if self.bar is not None:
            self.bar.close()
