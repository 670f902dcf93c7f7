"""One background compile of a thing at a time on this machine, whichever process asks.

A background helper (a pose loop's, :mod:`parasynth.engine.posefn`; the compiled crew's,
:func:`parasynth.engine.core.spin_warm`) compiles into numba's cache what every later process
then loads. Processes that ask at the same time (two runs in a row while the first one's helper
still compiles, a study's worker processes) would each start a helper for the same kernel: the
same seconds of CPU and up to half a gigabyte of memory twice. So a helper first *holds* its
compile: a file made with ``O_EXCL`` beside what it compiles, naming its process. A second
helper finding the file held by a live helper waits for it to be let go, then ends without
compiling (the kernel is in the cache by then): its starter loads it as it would its own. A
file whose process is gone (a helper killed on Ctrl-C) is taken over.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

__all__ = ["hold", "let_go", "holder", "wait_let_go", "MAKING"]

#: What a holder's command line contains: a process whose line lacks it is not a helper (its
#: process id reused).
HELPER_MARK = "parasynth.engine."


def _alive(pid: int) -> bool:
    """Whether process ``pid`` lives and is a parasynth helper (as far as /proc tells)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's: alive
        return True
    except OSError:
        return False
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return HELPER_MARK.encode() in f.read()
    except OSError:  # no /proc: trust the signal
        return True


#: Seconds a file without a process id counts as held (made, its id not yet written).
MAKING = 5.0


def holder(path: Path) -> int | None:
    """The process id holding ``path`` if that process lives (0: the file was made less than
    :data:`MAKING` seconds ago and its holder has not written its id yet), else None."""
    path = Path(path)
    try:
        text = path.read_text().strip()
        if not text:
            return 0 if time.time() - path.stat().st_mtime < MAKING else None
        pid = int(text)
    except (OSError, ValueError):
        return None
    return pid if _alive(pid) else None


def hold(path: Path) -> bool:
    """Hold ``path`` for this process: True when it was free (or held by a process that is
    gone), False when a live helper holds it. True also when the file cannot be made (a
    folder that cannot be written: nobody can hold it then)."""
    path = Path(path)
    for _ in range(2):
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600)
        except FileExistsError:
            if holder(path) is not None:
                return False
            try:  # a holder that is gone: take it over
                path.unlink()
            except FileNotFoundError:
                pass
            except OSError:
                return True
            continue
        except OSError:
            return True
        with os.fdopen(fd, "w") as f:
            f.write(str(os.getpid()))
        return True
    return False


def let_go(path: Path) -> None:
    """Let ``path`` go (if this process holds it)."""
    path = Path(path)
    try:
        if path.read_text().strip() == str(os.getpid()):
            path.unlink()
    except (OSError, ValueError):
        pass


def wait_let_go(path: Path, poll: float = 0.2, timeout: float | None = None) -> bool:
    """Wait until no live process holds ``path``: True, or False after ``timeout`` seconds."""
    t0 = time.monotonic()
    while holder(path) is not None:
        if timeout is not None and time.monotonic() - t0 > timeout:
            return False
        time.sleep(poll)
    return True
