"""The names of derived result columns, in one place.

A study's objectives and design constraints each give a column named by their label; the run
adds derived columns beside them, named ``<label><suffix>``:

* ``_stderr``: the standard error of the final re-evaluation's mean (objectives, constraints);
* ``_margin``: a design constraint's margin (>= 0: met), in the constraint's unit;
* ``_nominal``: a robust item's value at the nominal design (no scatter);
* ``_robust_se``: the standard error of a robust item's statistic over the scatter draws.

Every module that writes or reads these columns builds their names here.
"""

from __future__ import annotations

__all__ = ["STDERR", "MARGIN", "NOMINAL", "ROBUST_SE", "DERIVED_SUFFIXES", "stderr", "margin", "nominal",
           "robust_se", "split_derived"]

STDERR = "_stderr"
MARGIN = "_margin"
NOMINAL = "_nominal"
ROBUST_SE = "_robust_se"
#: Every derived column suffix.
DERIVED_SUFFIXES = (STDERR, MARGIN, NOMINAL, ROBUST_SE)


def stderr(label: str) -> str:
    """``volume`` -> ``volume_stderr``."""
    return label + STDERR


def margin(label: str) -> str:
    """``footprint`` -> ``footprint_margin``."""
    return label + MARGIN


def nominal(label: str) -> str:
    """``volume`` -> ``volume_nominal``."""
    return label + NOMINAL


def robust_se(label: str) -> str:
    """``volume`` -> ``volume_robust_se``."""
    return label + ROBUST_SE


def split_derived(name: str, known=None) -> tuple[str, str]:
    """``(label, suffix)`` of a derived column name (``("volume", "_stderr")``), ``(name, "")``
    for any other; with ``known`` (a predicate on labels) only a suffix whose label it accepts."""
    for sfx in DERIVED_SUFFIXES:
        if name.endswith(sfx) and len(name) > len(sfx) and (known is None or known(name[: -len(sfx)])):
            return name[: -len(sfx)], sfx
    return name, ""
