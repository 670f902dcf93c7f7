"""One background compile of a thing at a time on the machine (parasynth.engine.held): a
helper holds its compile in a file naming its process; another helper waits for it instead of
compiling the same kernel beside it; a file whose process is gone is taken over."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

import pytest

from parasynth.engine import held, posefn, precompile


def _helper_like(*extra: str) -> subprocess.Popen:
    """A live process whose command line names a parasynth helper (it only sleeps), once it
    runs that command line (before its exec it has the test's)."""
    p = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)", "parasynth.engine.posefn", *extra])
    t0 = time.monotonic()
    while time.monotonic() - t0 < 20:
        try:
            with open(f"/proc/{p.pid}/cmdline", "rb") as f:
                if b"parasynth.engine.posefn" in f.read():
                    break
        except OSError:
            break  # no /proc: the signal alone tells
        time.sleep(0.005)
    return p


def _plain() -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])


@pytest.fixture
def procs():
    out = []
    yield out
    for p in out:
        p.kill()
        p.wait()


def test_the_first_holds_a_second_does_not_and_a_let_go_frees_it(tmp_path, procs):
    mark = tmp_path / "x.held"
    assert held.hold(mark)
    assert mark.read_text() == str(os.getpid())
    other = _helper_like()
    procs.append(other)
    mark.write_text(str(other.pid))
    assert held.holder(mark) == other.pid
    assert not held.hold(mark)  # held by a live helper
    held.let_go(mark)  # not ours: left alone
    assert mark.read_text() == str(other.pid)
    other.kill()
    other.wait()
    assert held.holder(mark) is None
    assert held.hold(mark)  # its process is gone: taken over
    assert mark.read_text() == str(os.getpid())
    held.let_go(mark)
    assert not mark.exists()


def test_a_process_id_reused_by_another_program_does_not_hold(tmp_path, procs):
    mark = tmp_path / "x.held"
    p = _plain()
    procs.append(p)
    mark.write_text(str(p.pid))
    assert held.holder(mark) is None
    assert held.hold(mark)


def test_a_file_just_made_counts_as_held_until_its_id_is_written(tmp_path):
    mark = tmp_path / "x.held"
    mark.write_text("")  # made by another process, which has not written its id yet
    assert held.holder(mark) == 0 and not held.hold(mark)
    old = time.time() - 2 * held.MAKING
    os.utime(mark, (old, old))  # ... and never will (it died between the two)
    assert held.holder(mark) is None and held.hold(mark)


def test_a_folder_that_cannot_be_written_blocks_nobody(tmp_path):
    assert held.hold(tmp_path / "missing" / "x.held")


def test_waiting_ends_when_the_holder_ends(tmp_path, procs):
    mark = tmp_path / "x.held"
    other = _helper_like()
    procs.append(other)
    mark.write_text(str(other.pid))
    assert not held.wait_let_go(mark, poll=0.01, timeout=0.1)
    threading.Timer(0.2, other.kill).start()
    t0 = time.monotonic()
    assert held.wait_let_go(mark, poll=0.01, timeout=20)
    assert time.monotonic() - t0 >= 0.1


def test_a_pose_loop_helper_waits_for_another_compiling_the_same_module(tmp_path, procs, monkeypatch):
    module = tmp_path / "pose_loop_abc.py"
    module.write_text("")
    mark, done = module.with_suffix(".held"), module.with_suffix(".done")
    compiled = []
    monkeypatch.setattr(posefn, "_load", lambda path: compiled.append(path))
    monkeypatch.setattr(held, "wait_let_go", lambda path, **kw: _finish(other, done))
    other = _helper_like(str(module))
    procs.append(other)
    mark.write_text(str(other.pid))

    def _finish(p, done_file):  # the other helper compiles the module, marks it done and ends
        done_file.write_text("")
        p.kill()
        p.wait()
        return True

    assert posefn.main([str(module)]) == 0
    assert compiled == []  # loaded by the other one: nothing compiled here
    # the other one ends without marking it done (it failed, it was killed): compiled here
    done.unlink()
    other2 = _helper_like(str(module))
    procs.append(other2)
    mark.write_text(str(other2.pid))
    monkeypatch.setattr(held, "wait_let_go", lambda path, **kw: (other2.kill(), other2.wait()))
    assert posefn.main([str(module)]) == 0
    assert compiled == [module] and done.exists() and not mark.exists()


def test_a_free_pose_loop_module_is_compiled_held_and_let_go(tmp_path, monkeypatch):
    module = tmp_path / "pose_loop_abc.py"
    module.write_text("")
    mark = module.with_suffix(".held")
    seen = []
    monkeypatch.setattr(posefn, "_load", lambda path: seen.append(mark.read_text()))
    assert posefn.main([str(module)]) == 0
    assert seen == [str(os.getpid())] and not mark.exists() and module.with_suffix(".done").exists()


def test_the_compiled_crews_helper_holds_its_file_and_waits_for_another(tmp_path, procs, monkeypatch):
    mark = tmp_path / "crew.held"
    order = []
    monkeypatch.setattr(precompile, "_compile", lambda n: order.append((n, mark.read_text())))
    other = _helper_like()
    procs.append(other)
    mark.write_text(str(other.pid))
    monkeypatch.setattr(held, "wait_let_go", lambda path, **kw: (order.append("waited"), other.kill(), other.wait()))
    assert precompile.main(["_spin_done", "--hold", str(mark), "_crew_spin"]) == 0
    me = str(os.getpid())
    assert order == ["waited", ("_spin_done", me), ("_crew_spin", me)]
    assert not mark.exists()
    assert precompile.main(["_spin_done", "--hold"]) == 2


def test_the_compiled_crews_helper_is_started_holding_a_file_of_its_numba_cache(tmp_path, monkeypatch):
    from parasynth.engine import core

    monkeypatch.setenv("PARASYNTH_CACHE_DIR", str(tmp_path / "pc"))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "a"))
    a = core._serve_mark()
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "b"))
    b = core._serve_mark()
    assert a != b and a.parent == b.parent == tmp_path / "pc" / "held" and a.suffix == ".held"
    started = []
    monkeypatch.setattr(core._subprocess, "Popen", lambda cmd, **kw: started.append(cmd))
    monkeypatch.setattr(core, "_SERVE_HELPER", None)
    core._start_serve_helper()
    cmd = started[0]
    assert cmd[cmd.index("--hold") + 1] == str(b)
    assert cmd[3:3 + len(core.SERVE_KERNELS)] == list(core.SERVE_KERNELS)
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", "off")
    assert core._serve_mark() is None
