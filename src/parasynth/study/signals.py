"""Safe interrupts for every runner.

:class:`Interrupt` replaces the SIGINT (Ctrl-C) and SIGTERM handlers while a run works. The
first signal asks the run to stop after the design being evaluated; it is finished and
recorded, the tables are written and the run returns ``interrupted=True``. A second signal
while a design is being evaluated drops that design (it is not recorded, a resumed run
evaluates it again). A signal never interrupts a write to the journal or the storage.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading

__all__ = ["Interrupt"]


class Interrupt:
    """Graceful SIGINT/SIGTERM handling (see the module docstring). ``on_signal(signum)`` is
    called on every signal (the parent of local workers forwards it)."""

    def __init__(self, on_signal=None, quiet: bool = False):
        self.requested = False
        self.count = 0
        self._evaluating = False
        self._old = {}
        self.on_signal = on_signal
        self.quiet = quiet

    def _handler(self, signum, frame):
        self.count += 1
        first = not self.requested
        self.requested = True
        if self.on_signal is not None:
            self.on_signal(signum)
        if first:
            if not self.quiet:
                print("\ninterrupt: finishing the current design, then stopping "
                      "(press Ctrl-C again to drop it)", file=sys.stderr, flush=True)
        elif self._evaluating:
            self._evaluating = False
            raise KeyboardInterrupt

    @contextlib.contextmanager
    def evaluating(self):
        """Around a design evaluation: the only place a second signal may raise."""
        self._evaluating = True
        try:
            yield
        finally:
            self._evaluating = False

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for s in (signal.SIGINT, signal.SIGTERM):
                self._old[s] = signal.signal(s, self._handler)
        return self

    def __exit__(self, *exc):
        for s, h in self._old.items():
            signal.signal(s, h)
        self._old = {}
