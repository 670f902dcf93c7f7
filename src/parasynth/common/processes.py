"""The engine's helper processes: whether to start them, and their environment (read without
importing the engine)."""

from __future__ import annotations

import os

__all__ = ["helper_env", "compile_ahead_off"]


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
