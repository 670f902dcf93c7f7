"""One enumeration of each motion per test process, shared by the structure test modules, and
the xdist group that keeps the tests of one motion on one test worker (``--dist loadgroup``),
so that a motion is enumerated once in the whole run rather than once per worker that meets it."""

from __future__ import annotations

import functools
import os

import pytest

from parasynth.structures import structures

#: Checking processes of an enumeration: one in a test worker of a parallel run (the other
#: workers hold the other cores: forked checkers would only contend with them, ~10 % slower
#: measured with two workers), the default otherwise.
PROCESSES = 1 if int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1") or 1) > 1 else None


@functools.lru_cache(maxsize=None)
def enumerated(motion: str, all_axes: bool = False):
    """``structures(motion, all_axes=all_axes)`` with the other arguments at their defaults (the
    checking processes: :data:`PROCESSES`; the structures do not depend on them)."""
    return structures(motion, all_axes=all_axes, processes=PROCESSES)


def motion_group(motion: str):
    """The mark that sends a test of ``motion``'s enumeration to the worker of its group."""
    return pytest.mark.xdist_group(f"structures-{motion}")


def per_motion(motions, *extra):
    """``pytest.param`` per motion (or per ``(motion, ...)`` tuple), each in its motion's group."""
    out = []
    for m in motions:
        values = m if isinstance(m, tuple) else (m,)
        out.append(pytest.param(*values, *extra, marks=motion_group(values[0])))
    return out
