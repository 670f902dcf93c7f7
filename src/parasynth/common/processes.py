"""The engine's helper processes: whether to start them, and their environment (read without
importing the engine)."""

from __future__ import annotations

import hashlib
import os

__all__ = ["helper_env", "compile_ahead_off", "numba_cache_subdir"]


def compile_ahead_off() -> bool:
    """Whether compiling ahead is turned off (``PARASYNTH_COMPILE_AHEAD=0``): no helper
    processes, no notice said ahead, no background compile; each run compiles what it uses as
    it meets it."""
    return os.environ.get("PARASYNTH_COMPILE_AHEAD", "").strip() == "0"


def helper_env() -> dict:
    """The environment of a helper process: this one's, with the parasynth this process runs
    first on ``PYTHONPATH`` (a source tree put on ``sys.path`` by a script, a test)."""
    env = dict(os.environ)
    src = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env["PYTHONPATH"] = src + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


def numba_cache_subdir(source: str) -> str:
    """The folder numba gives the functions of the file ``source`` under ``NUMBA_CACHE_DIR`` or
    its user-wide cache (its locators' ``get_suitable_cache_subpath``: the folder's name and the
    SHA-1 of its absolute path)."""
    folder = os.path.dirname(os.path.abspath(source))
    return f"{os.path.basename(folder)}_{hashlib.sha1(folder.encode()).hexdigest()}"
