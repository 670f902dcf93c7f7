"""The generated pose loops (parasynth.engine.posefn) against the interpreter they replace.

For every shipped mechanism, the compiled pose, feasibility and margins kernels run the same
poses once with the program's generated loop and once with the interpreter: every output must
be identical bit for bit (the loop computes the same operations in the same order). The poses
cover the task box and beyond it, NaN and infinite coordinates, and angles beyond the
polynomial sine's range (the loop hands those sub-blocks back to the interpreter).
"""

from __future__ import annotations

import numpy as np
import pytest

from parasynth import list_mechanisms, load_mechanism
from parasynth.engine import core, posefn
from parasynth.measures.workspace import _check_ranges

pytestmark = pytest.mark.skipif(not core.HAVE_NUMBA, reason="the compiled engine needs numba")

MECHS = list_mechanisms()


def _poses(mech, n=700, seed=3):
    rng = np.random.default_rng(seed)
    coords, lo, hi = _check_ranges(mech, mech.default_ranges())
    X = np.tile(np.asarray(mech.home, dtype=float), (n, 1))
    span = hi - lo
    cols = [mech.task_coordinates.index(c) for c in coords]
    X[:, cols] = rng.uniform(lo - 0.2 * span, hi + 0.2 * span, (n, len(lo)))
    X[5, 0] = np.nan
    X[17, -1] = np.inf
    ang = [j for j, c in enumerate(mech.task_coordinates) if c in mech.angular_coordinates]
    if ang:
        X[300, ang[0]] = 3e7  # the polynomial sine's range exceeded: the interpreter for that sub-block
    return np.ascontiguousarray(X)


def _with(prog, fn):
    posefn._STATE[prog] = [fn, None]


def _same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    assert np.array_equal(a.view(np.uint8) if a.dtype == bool else a, b.view(np.uint8) if b.dtype == bool else b,
                          equal_nan=a.dtype != bool)


@pytest.mark.parametrize("name", MECHS)
def test_a_generated_pose_loop_gives_the_interpreters_bits(name):
    mech = load_mechanism(name)
    plan = core.build_plan(mech, list(mech.constraints.values()))
    prog = plan.program
    loop = posefn.build(prog, core.SUB)
    assert loop is not posefn.NONE, f"{name}: no loop generated for its {prog.n_pose} instructions"
    X = _poses(mech)
    out = {}
    for label, fn in (("loop", loop), ("interpreter", posefn.NONE)):
        _with(prog, fn)
        assert core.run_feasible(plan, X)[0].shape == (X.shape[0],)
        out[label] = (core.run_feasible(plan, X, extents=True), core.run_margins(plan, X),
                      core.run_pose(prog, plan.consts, X))
    (f1, m1, p1), (f2, m2, p2) = out["loop"], out["interpreter"]
    for a, b in zip(f1, f2):
        _same(a, b)
    _same(m1[0], m2[0])
    assert m1[1] == m2[1]
    for a, b in zip(p1[:3], p2[:3]):
        _same(a, b)
    # the loop ran and answered most poses (not every sub-block handed back to the interpreter)
    assert np.count_nonzero(p1[0]) > 0


@pytest.mark.parametrize("name", ["5pus_upu", "2rpu_2sps", "gough_stewart_6ups"])
def test_the_twist_programs_loop_gives_the_interpreters_twist_map(name):
    mech = load_mechanism(name)
    prog, consts = core.program_constants(mech, {}, twist=True)
    loop = posefn.build(prog, core.SUB)
    assert loop is not posefn.NONE
    X = _poses(mech, seed=5)
    _with(prog, loop)
    a = core.run_pose(prog, consts, X, twist=True)
    _with(prog, posefn.NONE)
    b = core.run_pose(prog, consts, X, twist=True)
    for u, v in zip(a, b):
        _same(u, v)


def test_the_generated_source_refuses_what_it_does_not_compute():
    mech = load_mechanism("5pus_upu")
    prog = core.build_plan(mech, list(mech.constraints.values())).program
    src = posefn.source(prog, core.SUB)
    assert src is not None and "_sincos" in src
    # an opcode outside the generated set makes the program the interpreter's
    ins = prog.ins.copy()
    ins[0, 0] = core.OPS["nop"]
    bad = type(prog)(ins, prog.n_task, prog.n_reg, prog.const_base, prog.literals, prog.param_keys,
                     prog.const_param, prog.n_pose, prog.pose_regs, prog.valid_regs, prog.margin_regs, prog.twist_regs)
    assert posefn.source(bad, core.SUB) is None
    # a register read before any instruction wrote it (not a coordinate or constant): refused
    ins = prog.ins.copy()
    ins[0, 2] = prog.n_reg - 1
    bad = type(prog)(ins, prog.n_task, prog.n_reg, prog.const_base, prog.literals, prog.param_keys,
                     prog.const_param, prog.n_pose, prog.pose_regs, prog.valid_regs, prog.margin_regs, prog.twist_regs)
    assert posefn.source(bad, core.SUB) is None


def test_without_a_cache_folder_the_interpreter_runs(monkeypatch):
    monkeypatch.setenv("PARASYNTH_POSE_LOOPS", "1")
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", "off")
    mech = load_mechanism("3rps")
    prog = core.build_plan(mech, list(mech.constraints.values())).program
    posefn._STATE.pop(prog, None)
    assert posefn.function(prog, core.SUB) is posefn.NONE


def test_a_run_gets_its_loop_from_a_helper_process_and_loads_it_later(monkeypatch, tmp_path):
    """The path a run takes: the first call starts the compiling helper and answers with the
    interpreter; once the helper is done, a call loads the compiled loop, and a new process
    (here: the state forgotten) loads it from the cache without a helper."""
    monkeypatch.setenv("PARASYNTH_POSE_LOOPS", "1")
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", str(tmp_path))
    mech = load_mechanism("3prs")
    plan = core.build_plan(mech, list(mech.constraints.values()))
    prog = plan.program
    posefn._STATE.pop(prog, None)
    assert posefn.function(prog, core.SUB) is posefn.NONE  # the helper started, nothing compiled here
    path = posefn._paths(prog, core.SUB)[0]
    helper = posefn._HELPERS[str(path)]
    assert helper.wait(timeout=300) == 0
    loop = posefn.function(prog, core.SUB)
    assert loop is not posefn.NONE
    X = _poses(mech, n=500, seed=9)
    a = core.run_feasible(plan, X, extents=True)
    posefn._STATE[prog] = [posefn.NONE, None]
    b = core.run_feasible(plan, X, extents=True)
    for u, v in zip(a, b):
        _same(u, v)
    posefn._STATE.pop(prog, None)
    posefn._LOADED.pop(str(path), None)
    posefn._HELPERS.pop(str(path), None)
    assert posefn.function(prog, core.SUB) is not posefn.NONE  # from the cache, no new helper
    assert str(path) not in posefn._HELPERS


def _marked_done(name, text, monkeypatch, tmp_path):
    """(program, module path, done marker) of mechanism ``name``'s loop, its module written with
    ``text`` (given the module body) and marked done in a cache folder of its own, loops on."""
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", str(tmp_path))
    mech = load_mechanism(name)
    prog = core.build_plan(mech, list(mech.constraints.values())).program  # (its checks run no helper: loops off)
    monkeypatch.setenv("PARASYNTH_POSE_LOOPS", "1")
    posefn._STATE.pop(prog, None)
    path, done, body = posefn._paths(prog, core.SUB)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text(body))
    done.write_text("")
    return prog, path, done


def test_a_broken_loop_module_leaves_the_interpreter(monkeypatch, tmp_path):
    prog, path, done = _marked_done("3rps", lambda body: "this is not python\n", monkeypatch, tmp_path)
    cached = path.parent / "__pycache__" / f"{path.stem}.loop-1.py311.nbi"  # as if numba's cache had it
    cached.parent.mkdir(exist_ok=True)
    cached.write_text("")
    posefn._LOADED.pop(str(path), None)
    assert posefn.function(prog, core.SUB) is posefn.NONE


def test_a_loop_marked_done_but_missing_from_numbas_cache_is_compiled_again_by_a_helper(monkeypatch, tmp_path):
    # done, but never compiled into this numba cache
    prog, path, done = _marked_done("2rpu_2sps", posefn._module_text, monkeypatch, tmp_path)
    assert not posefn._in_numba_cache(path)
    assert posefn.function(prog, core.SUB) is posefn.NONE  # not compiled here: a helper instead
    assert not done.exists()
    assert posefn._HELPERS[str(path)].wait(timeout=300) == 0
    assert posefn._in_numba_cache(path)
    assert posefn.function(prog, core.SUB) is not posefn.NONE
