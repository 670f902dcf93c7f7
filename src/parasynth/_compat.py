"""The flat module paths of earlier releases (``parasynth.legs``, ``parasynth.workspace``,
``parasynth.objectives``, ...) still import, as the same module objects as their places in the
packages (``parasynth.model.legs``, ``parasynth.measures.workspace``, ...): scripts, plugins and
runs written before the packages keep working, and a monkeypatch through either name patches
the one module.

Modules that ``import parasynth`` has loaded are entered in ``sys.modules`` under their old name
at once, and as attributes of the package where the name is free (so that importing
``parasynth.workspace`` never replaces the function ``parasynth.workspace`` with its module); the
others through a finder, on first import.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys

#: old dotted path -> the module's place in the packages
MOVED = {f"parasynth.{old}": f"parasynth.{new}" for old, new in {
    "spatial": "model.spatial", "legs": "model.legs", "mechanism": "model.mechanism",
    "constraints": "model.constraints", "geometry_checks": "model.geometry_checks",
    "workspace": "measures.workspace", "usable": "measures.usable", "indices": "measures.indices",
    "stiffness": "measures.stiffness", "accuracy": "measures.accuracy", "dynamics": "measures.dynamics",
    "robustness": "measures.robustness", "objectives": "measures.objectives",
    "measure_spec": "measures.measure_spec", "display": "measures.display",
    "units": "common.units", "validation": "common.validation", "yamlio": "common.yamlio",
    "qmc": "common.qmc", "pareto": "common.pareto",
    "kernels": "engine.kernels",
    "cli_export": "cli.export_cmd", "cli_study": "cli.study_cmd", "plugins": "cli.plugins",
}.items()}


class _Alias(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds an old path and hands out the module at its new place (not a copy)."""

    def find_spec(self, name, path=None, target=None):
        if name not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(name, self)

    def create_module(self, spec):
        module = importlib.import_module(MOVED[spec.name])
        self._spec = module.__spec__  # the import system sets __spec__ to the alias's; put it back
        return module

    def exec_module(self, module):
        module.__spec__ = self._spec


def install() -> None:
    package = sys.modules["parasynth"]
    for old, new in MOVED.items():
        if new in sys.modules:
            sys.modules.setdefault(old, sys.modules[new])
            name = old.rsplit(".", 1)[1]
            if not hasattr(package, name):  # ``import parasynth.legs; parasynth.legs.SPS`` as before
                setattr(package, name, sys.modules[new])
    if not any(isinstance(f, _Alias) for f in sys.meta_path):
        sys.meta_path.append(_Alias())
