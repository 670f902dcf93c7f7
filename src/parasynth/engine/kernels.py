"""Compatibility names for the compiled feasibility engine (now :mod:`parasynth.engine`).

* :func:`feasible_fast` ``(mech, X)`` -> (N,) bool, ``mech.is_feasible(X)`` by the compiled
  engine where it covers ``mech`` (else the NumPy reference);
* :func:`margins_fast` ``(mech, X)`` -> {constraint name: (N,) margin};
* :func:`kernel_available` ``(mech)`` -> whether the compiled engine covers ``mech``;
* ``HAVE_NUMBA``: whether numba is importable (and not disabled by ``PARASYNTH_NO_NUMBA``).

Unlike the engine's default path, these fall back to NumPy silently (no warning): callers
that need to know ask :func:`kernel_available`.
"""

from __future__ import annotations

from .. import engine as _engine
from . import HAVE_NUMBA
from .core import BLOCK, SUB, KernelPlan, build_plan

__all__ = ["HAVE_NUMBA", "feasible_fast", "margins_fast", "kernel_available", "KernelPlan", "build_plan", "BLOCK",
           "SUB"]


def kernel_available(mech) -> bool:
    """Whether :func:`feasible_fast` runs the compiled engine for ``mech`` (all constraints)."""
    return HAVE_NUMBA and _engine.available(mech)


def feasible_fast(mech, X):
    """(N,) bool: reachable and every constraint of ``mech`` satisfied at poses ``X``."""
    if not kernel_available(mech):
        return mech.is_feasible(X, engine="numpy")
    return _engine.feasible(mech, X)


def margins_fast(mech, X) -> dict:
    """{constraint name: (N,) margin} for all constraints, as ``mech.constraint_margins(X)``."""
    if not kernel_available(mech):
        return mech.constraint_margins(X, engine="numpy")
    return _engine.margins(mech, X)
