"""Compiling ahead from the start of a run (precompile.start_early): helpers start at once with
the interpreter kernels apart from the others, compile_ahead waits for them instead of
compiling the same kernels again, and afterwards every kernel is in the cache."""

import os
import subprocess
import sys

import pytest

from parasynth import engine

pytestmark = pytest.mark.skipif(not engine.HAVE_NUMBA, reason="numba not available")

CODE = r"""
import time
from parasynth.engine import precompile as pre
from numba.core import event
compiled = []
class L(event.Listener):
    def on_start(self, e):
        compiled.append(getattr(e.data.get("dispatcher"), "py_func", None).__name__)
    def on_end(self, e):
        pass
event.register("numba:compile", L())
t0 = time.perf_counter()
shares = pre.start_early(["constraint_rank"])
started = time.perf_counter() - t0
print("shares", shares)
print("running", sorted(n for n, r in pre.early().items() if r))
print("again", pre.start_early(["constraint_rank"]))  # nothing twice
out = pre.compile_ahead(pre.missing(["constraint_rank"]))
print("waited", sorted(out["waited"]), "local", out["local"], "helpers", out["helpers"], "failed", out["failed"])
print("cached", pre.in_cache("_pose_kernel"), pre.in_cache("_constraint_rank_kernel"))
print("compiled_here", compiled)
print("started_s", started)
"""


def test_start_early_then_compile_ahead_waits(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    r = subprocess.run([sys.executable, "-c", CODE], env=env, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr
    lines = dict(line.split(" ", 1) for line in r.stdout.strip().splitlines())
    assert lines["shares"] == "[['_pose_kernel'], ['_constraint_rank_kernel']]"
    assert lines["running"] == "['_constraint_rank_kernel', '_pose_kernel']"
    assert lines["again"] == "[]"
    assert lines["waited"].startswith("['_constraint_rank_kernel', '_pose_kernel'] local [] helpers [] failed []")
    assert lines["cached"] == "True True"
    assert lines["compiled_here"] == "[]"  # compiled by the helpers only
    assert float(lines["started_s"]) < 10.0  # returns at once (imports of the engine included)
