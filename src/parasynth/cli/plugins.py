"""User plugins: modules that register measures (objectives, constraints) on import.

``PARASYNTH_PLUGINS`` lists them, comma-separated, as importable module names or paths of
``.py`` files. Both the command line and the study runner (including its worker processes)
call :func:`load_plugins`, so it lives below both.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys

__all__ = ["load_plugins"]


def load_plugins(spec: str | None = None) -> None:
    """Import user modules that register measures (``PARASYNTH_PLUGINS``: comma-separated
    module names or .py file paths). ``spec`` overrides the environment variable."""
    spec = os.environ.get("PARASYNTH_PLUGINS", "") if spec is None else spec
    for item in filter(None, (s.strip() for s in spec.split(","))):
        if item.endswith(".py"):
            mod_name = "parasynth_plugin_" + os.path.splitext(os.path.basename(item))[0]
            sp = importlib.util.spec_from_file_location(mod_name, item)
            if sp is None or not os.path.exists(item):
                raise SystemExit(f"error: PARASYNTH_PLUGINS: cannot load {item!r}")
            mod = importlib.util.module_from_spec(sp)
            sys.modules[mod_name] = mod
            sp.loader.exec_module(mod)
        else:
            importlib.import_module(item)
