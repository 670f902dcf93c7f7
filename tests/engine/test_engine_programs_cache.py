"""Programs kept on disk (parasynth.common.cache, kind ``programs``): a process that meets a
description whose program another process built reads it back instead of translating the
description again (tens to hundreds of milliseconds a structure), checks it against the NumPy
pose as a new one, and evaluates as the built one does; a description whose task, margins or
flags differ builds its own."""
from __future__ import annotations

import numpy as np
import pytest

import parasynth
from parasynth.engine import core

needs_numba = pytest.mark.skipif(not core.HAVE_NUMBA, reason="numba is not installed")


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", str(tmp_path / "c"))
    monkeypatch.setattr(core, "_PROGRAMS", {})  # this process's programs: as a new process
    return tmp_path / "c"


@pytest.fixture
def builds(monkeypatch):
    calls = []
    real = core.build_program

    def counted(mech, *a, **k):
        calls.append(mech.name)
        return real(mech, *a, **k)

    monkeypatch.setattr(core, "build_program", counted)
    return calls


def _fresh_process(monkeypatch):
    monkeypatch.setattr(core, "_PROGRAMS", {})


@needs_numba
def test_a_program_is_read_back_and_evaluates_as_built(folder, builds, monkeypatch):
    m1 = parasynth.load_mechanism("3rps")
    built = core.program_for(m1, {}, twist=True)
    assert builds == ["3rps"] and len(list((folder / "programs").glob("*.pickle"))) == 1
    _fresh_process(monkeypatch)
    m2 = m1.with_params(platform_radius=0.17, q_max=0.65)  # another design: the same program
    checked = []
    real_check = core._check_program
    monkeypatch.setattr(core, "_check_program", lambda *a: (checked.append(True), real_check(*a)))
    read = core.program_for(m2, {}, twist=True)
    assert builds == ["3rps"] and checked == [True]  # read, not built; checked as a new program
    assert read is not built
    for k in ("ins", "literals", "const_param", "pose_regs", "valid_regs", "twist_regs"):
        assert np.array_equal(getattr(read, k), getattr(built, k), equal_nan=k == "literals")
    # the read program gives the NumPy pose and twist map of the new design
    X = m2.home + np.random.default_rng(0).normal(scale=0.02, size=(64, m2.n_task))
    ok, p, R, T = core.run_pose(read, read.constants(m2._penv), X, True)
    valid = m2.pose_valid(X)
    assert np.array_equal(ok, valid) and valid.any()
    p0, R0 = m2.pose(X[valid])
    np.testing.assert_allclose(p[valid], p0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(R[valid], R0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(T[valid], m2.twist_map(X[valid]), rtol=0, atol=1e-10)


@needs_numba
def test_other_margins_flags_or_tasks_build_their_own(folder, builds, monkeypatch):
    m = parasynth.load_mechanism("3rps")
    core.program_for(m, {}, twist=False)
    _fresh_process(monkeypatch)
    core.program_for(m, {}, twist=True)  # another flag
    other = parasynth.load_mechanism("3prs")  # another description (its task differs)
    _fresh_process(monkeypatch)
    core.program_for(other, {}, twist=False)
    assert builds == ["3rps", "3rps", "3prs"]
    assert len(list((folder / "programs").glob("*.pickle"))) == 3
    assert core._program_content(m, {}, False, False) != core._program_content(other, {}, False, False)


@needs_numba
def test_a_damaged_program_file_is_built_again(folder, builds, monkeypatch):
    m = parasynth.load_mechanism("3rps")
    core.program_for(m, {})
    (f,) = (folder / "programs").glob("*.pickle")
    f.write_bytes(b"not a pickle")
    _fresh_process(monkeypatch)
    core.program_for(m, {})
    assert builds == ["3rps", "3rps"]


@needs_numba
def test_no_cache_folder_builds_every_process(tmp_path, builds, monkeypatch):
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", "off")
    m = parasynth.load_mechanism("3rps")
    for _ in range(2):
        _fresh_process(monkeypatch)
        core.program_for(m, {})
    assert builds == ["3rps", "3rps"]


@needs_numba
def test_a_mechanism_the_key_cannot_describe_is_built_and_not_kept(folder, builds, monkeypatch):
    """A described mechanism whose task the disk key cannot read (an attribute missing) is built
    and used as before, and nothing is written."""
    def no_key(*a):
        raise AttributeError("rot_axes")

    monkeypatch.setattr(core, "_program_content", no_key)
    m = parasynth.load_mechanism("3rps")
    prog = core.program_for(m, {})
    assert builds == ["3rps"] and prog.ins.shape[0] > 0
    assert not (folder / "programs").exists() or not list((folder / "programs").glob("*.pickle"))
