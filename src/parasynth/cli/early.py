"""A first run's compile, started before the run imports the engine.

On an empty compile cache the first run's critical path is one kernel's compile in a helper
process (the feasibility kernel, ~12-15 s; :func:`parasynth.engine.precompile.start_early`).
That helper can only start once the run has imported the engine (~0.6 s: numba, the kernels'
modules) to ask which kernels are missing, and then imports it again itself before compiling.
So ``parasynth run`` starts it first, from what it can tell without the engine: the study asks
for the compiled engine, and numba's cache has no index of the feasibility kernel (a file
looked for where numba keeps it). The helper (``python -m parasynth.engine.precompile
--early ...``) then computes the queue itself, exactly as ``start_early`` would, and claims
each kernel before compiling it; the run's ``start_early`` takes it as its queue's helper once
it has imported the engine. Where the guess is wrong either way nothing is lost but the guess:
an index that is there but stale (the engine's source changed) leaves the run to start its
helper as before, and a helper started for a cache that holds everything finds nothing to do
and ends.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ..common.processes import compile_ahead_off, helper_env, numba_cache_subdir

__all__ = ["FIRST", "probably_cached", "start", "stop"]

#: The kernel every early queue starts with (the longest compile, the feasibility kernel of
#: ``parasynth/engine/core.py``), whose index in numba's cache tells a filled cache.
FIRST = "_feasible_kernel"


def _numba_dirs(source: str) -> list[Path]:
    """Where numba keeps the cache of the functions of the file ``source``: ``NUMBA_CACHE_DIR``
    when set, else ``__pycache__`` beside it or, where that cannot be written, the user's numba
    cache folder (numba's locators, in their order)."""
    folder = os.path.dirname(os.path.abspath(source))
    sub = numba_cache_subdir(source)
    if os.environ.get("NUMBA_CACHE_DIR"):
        return [Path(os.environ["NUMBA_CACHE_DIR"]) / sub]
    user = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "numba" / sub
    return [Path(folder) / "__pycache__", user]


def probably_cached() -> bool:
    """Whether numba's cache holds an index of :data:`FIRST` (of any source line: a stale one
    counts, see the module docstring)."""
    source = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "engine", "core.py")
    pattern = f"core.{FIRST}-*.py{sys.version_info[0]}{sys.version_info[1]}.nbi"
    return any(next(d.glob(pattern), None) is not None for d in _numba_dirs(source) if d.is_dir())


def start(what: str, leg_types: list[str] | None = None):
    """Start the early helper for ``what`` (``"study"``, or ``"structure"`` with its
    ``leg_types``; :func:`parasynth.engine.precompile.early_kinds`) unless the cache seems
    filled, numba is not to be had, compiling ahead is off or this process has imported the
    engine already (nothing to win: ``start_early`` then asks numba's cache and this process's
    kernels exactly): ``(process, claim folder, started at)`` for ``start_early``'s
    ``helper``, or None."""
    if compile_ahead_off() or os.environ.get("PARASYNTH_NO_NUMBA", "").strip() not in ("", "0"):
        return None
    if "parasynth.engine.core" in sys.modules:  # imported already (a script, a test): start_early tells exactly
        return None
    if importlib.util.find_spec("numba") is None or probably_cached():
        return None
    folder = tempfile.mkdtemp(prefix="parasynth-claims-")
    cmd = [sys.executable, "-m", "parasynth.engine.precompile", "--early", what, *(leg_types or ()), "--claims", folder]
    try:
        p = subprocess.Popen(cmd, env=helper_env(), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    except OSError:
        shutil.rmtree(folder, ignore_errors=True)
        return None
    return p, folder, time.perf_counter()


def stop(helper) -> None:
    """End an early helper not taken by ``start_early`` and remove its claim folder."""
    if helper is None:
        return
    p, folder, _ = helper
    if p.poll() is None:
        p.kill()
    p.wait()
    shutil.rmtree(folder, ignore_errors=True)
