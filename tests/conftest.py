"""Shared pytest configuration: make ``tests/_support.py`` and the test modules of every test
folder importable from every test folder (including ``tests/reproduction``)."""

import os
import shutil
import sys
import tempfile

_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, _HERE)
# the test folders mirror the packages; a few test modules reuse another's checkers by module name
# (``from test_engine import check_mechanism``): every folder is importable whichever is collected first
for _d in sorted(os.listdir(_HERE)):
    if os.path.isdir(os.path.join(_HERE, _d)) and not _d.startswith((".", "_")) and _d != "data":
        sys.path.append(os.path.join(_HERE, _d))

from hypothesis import settings  # noqa: E402

# In CI the property-based tests draw a fixed sequence of examples (derandomize): a run's
# outcome depends only on the code. Locally they explore new examples each run.
settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


# The results parasynth keeps on disk between processes (sampled points, enumerated structures:
# parasynth.common.cache) go to a folder of this test session, shared by its workers, unless
# PARASYNTH_CACHE_DIR is set: every session computes them anew at least once, as a first run does.
_SESSION_CACHE = None
if "PARASYNTH_CACHE_DIR" not in os.environ:
    _SESSION_CACHE = os.environ["PARASYNTH_CACHE_DIR"] = tempfile.mkdtemp(prefix="parasynth-test-cache-")


# The generated pose loops (parasynth.engine.posefn) are compiled by a helper process per
# program once a run has seen it; across the suite's hundreds of descriptions those helpers would
# compete with the tests for the cores. The suite runs the interpreter unless a test asks for the
# loops (tests/engine/test_pose_loops.py compiles them in its process and compares them with it).
os.environ.setdefault("PARASYNTH_POSE_LOOPS", "0")


def pytest_unconfigure(config):
    if _SESSION_CACHE is not None and not os.environ.get("PYTEST_XDIST_WORKER"):
        shutil.rmtree(_SESSION_CACHE, ignore_errors=True)


def pytest_collection_modifyitems(config, items):
    """The tests of one motion's structure enumeration (``xdist_group`` marks, sent whole to one
    test worker by ``--dist loadgroup``) first: the longest work units start while the short
    tests fill the other worker, instead of ending the run on one busy worker."""
    items.sort(key=lambda item: item.get_closest_marker("xdist_group") is None)
