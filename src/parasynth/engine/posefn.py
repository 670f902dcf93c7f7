"""The pose part of a register program as one generated loop, compiled once per program.

The interpreter of :mod:`parasynth.engine.core` runs a program's pose part instruction by
instruction, each a loop over the sub-block's poses that reads its operands from the scratch
rows and writes its result back: ~0.5 ns a pose per instruction, the biggest single share of
a closed-form mechanism's feasibility (the 5-PUS/UPU's 23 instructions ~11 of its ~49 ns a
pose on one core, the coordinates' load and the pose's copy besides). A loop generated for one
program computes the same instructions lane by lane in locals, reading the inputs (task
coordinates, constants) once and writing each register's last value once: ~6-7 ns a pose
for the same program, the same operations in the same order, so the same bits (no fused
multiply-add, no reassociation: numba's ``fastmath=False``; the sine and cosine by the same
Cephes code, :mod:`parasynth.engine.sincos`).

* **Which programs.** Pose parts of at most :data:`MAX_INSTRUCTIONS` instructions using only
  the opcodes in :data:`_EMIT`: every closed-form description's (12-30 instructions, a loop
  compiled in ~1 s), and the unrolled Gauss-Newton of the 1T2R structures' parasitic
  coordinates (3-RPS and 3-PRS 1,667 instructions: ~12 s and ~0.5 GB to compile, then 240 ns a
  pose against the interpreter's 1,115; 3-UPU 3,511: ~19 s and ~0.55 GB, 357 ns against
  1,926). The 3T0R structures' (5,000-6,500 instructions) keep the interpreter: ~50 s and
  ~1.2 GB to compile one (6x faster then), more than a background helper should take.
* **The same answer.** A lane whose angle needs libm (beyond ``_BIG_ANGLE``) or whose
  ``atan2`` radius is zero or not finite makes the generated loop return 1: the caller loads
  the coordinates again and runs the interpreter for that sub-block. The scratch rows are
  written at the rows the interpreter leaves them (each register's last value), so the
  margins and twist parts that follow read the same registers.
* **Compiled away from the run.** Generating a program's module is cheap; compiling it is
  ~1 s. :func:`function` never compiles in the calling process: the first time it sees a
  program it writes the module under the cache folder
  (:func:`parasynth.common.qmc.cache_dir`, ``pose_loops/``) and starts one helper process
  (``python -m parasynth.engine.posefn FILE``, at a lower scheduling priority, so that it takes a
  core the run leaves idle; numba's cache then holds the compiled loop);
  until the helper is done it returns :data:`NONE` (the interpreter runs). One helper compiles a
  module at a time on the machine (:mod:`parasynth.engine.held`): another process's helper for
  the same module (a second run while the first one's helper compiles, a study's workers)
  waits for it and compiles nothing. A later call, in
  this or any later process, loads the compiled loop from numba's cache (~ms). Without a cache
  folder (``PARASYNTH_CACHE_DIR=off``), on a cache that cannot be written, or with
  ``PARASYNTH_POSE_LOOPS=0``, the interpreter runs throughout.

The kernels take the loop as an argument (a first-class function of the signature
:data:`SIG`), so one kernel specialisation serves every program and the interpreter's
placeholder :data:`NONE`.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import subprocess
import sys
import threading
import weakref
from pathlib import Path

import numba
import numpy as np
from numba import cfunc
from numba import types as _nbt

from ..common.processes import numba_cache_subdir
from ..common.qmc import cache_dir
from . import held
from .program import OPS, Program

__all__ = ["SIG", "FN_TYPE", "NONE", "MAX_INSTRUCTIONS", "source", "function", "build", "main"]

#: Signature of a generated pose loop: (the data of the scratch rows (n_reg, SUB), poses of the
#: sub-block) ->
#: 0 done, 1 a lane needs the interpreter (the caller reloads the coordinates and runs it), -1
#: not run (the placeholder).
SIG = _nbt.int64(_nbt.CPointer(_nbt.float64), _nbt.int64)
#: The kernels' argument type of a pose loop.
FN_TYPE = _nbt.FunctionType(SIG)


@cfunc(SIG, cache=True, nogil=True)
def NONE(Rg, nb):  # noqa: N802 - a constant
    """The placeholder: the interpreter runs the pose part."""
    return -1


#: Pose parts longer than this keep the interpreter (the loop's compile grows faster than its
#: length: ~12 s at 1,667 instructions, ~19 s at 3,511, ~49 s and 1.2 GB at 6,456).
MAX_INSTRUCTIONS = 4000
#: Bumped whenever the generated code changes (part of each module's name).
_VERSION = 3

_BIN = {"add": "{a} + {b}", "sub": "{a} - {b}", "mul": "{a} * {b}", "div": "{a} / {b}",
        "madd": "{a} * {b} + {c}", "msub": "{a} * {b} - {c}", "rmsub": "{c} - {a} * {b}",
        "mmadd": "{a} * {b} + {c} * {e}", "mmsub": "{a} * {b} - {c} * {e}",
        "neg": "-{a}", "square": "{a} * {a}", "sqrt": "math.sqrt({a})", "abs": "abs({a})", "copy": "{a}",
        "lt": "1.0 if {a} < {b} else 0.0", "le": "1.0 if {a} <= {b} else 0.0",
        "gt": "1.0 if {a} > {b} else 0.0", "ge": "1.0 if {a} >= {b} else 0.0",
        "and": "1.0 if ({a} != 0.0 and {b} != 0.0) else 0.0",
        "select": "{a} if {c} != 0.0 else {b}",
        "min": "np.nan if ({a} != {a} or {b} != {b}) else ({a} if {a} <= {b} else {b})",
        "max": "np.nan if ({a} != {a} or {b} != {b}) else ({a} if {a} >= {b} else {b})",
        "sign": "np.nan if {a} != {a} else (1.0 if {a} > 0.0 else (-1.0 if {a} < 0.0 else 0.0))",
        # as core._run and core._unary (libm: these keep the loop scalar)
        "pow": "{a} ** {b}", "atan2": "math.atan2({a}, {b})", "hypot": "math.hypot({a}, {b})",
        "tan": "math.tan({a})", "atan": "math.atan({a})", "exp": "math.exp({a})", "sinh": "math.sinh({a})",
        "cosh": "math.cosh({a})", "tanh": "math.tanh({a})", "sin": "math.sin({a})", "cos": "math.cos({a})",
        "asin": "math.asin({a}) if -1.0 <= {a} <= 1.0 else np.nan",
        "acos": "math.acos({a}) if -1.0 <= {a} <= 1.0 else np.nan",
        "log": "math.log({a}) if {a} > 0.0 else (-np.inf if {a} == 0.0 else np.nan)"}
#: The opcodes a generated loop computes (as core._run does, expression for expression).
_EMIT = set(_BIN) | {"sincos", "sincos_atan2", "clip"}
_NAMES = {v: k for k, v in OPS.items()}


def source(prog: Program, sub: int) -> str | None:
    """The body of the generated pose loop of ``prog`` for sub-blocks of ``sub`` poses (the
    scratch rows indexed flat, row r at ``r * sub``: constant distances between rows, which
    lets the compiler vectorise the loop without run-time overlap checks), or None when the
    program is not one this module generates (see the module docstring)."""
    ins = np.asarray(prog.ins[:prog.n_pose])
    if not 0 < ins.shape[0] <= MAX_INSTRUCTIONS:
        return None
    fixed = set(range(prog.n_task)) | set(range(prog.const_base, prog.const_base + len(prog.literals)))
    cur: dict[int, str] = {}  # register -> the local holding its value now
    loads: list[int] = []
    body: list[str] = []
    count = [0]

    def rd(r: int) -> str | None:
        r = int(r)
        if r not in cur:
            if r not in fixed:  # read before any instruction wrote it: not a program we generate
                return None
            cur[r] = f"i{r}"
            loads.append(r)
        return cur[r]

    def wr(r: int) -> str:
        count[0] += 1
        cur[int(r)] = f"v{count[0]}"
        return cur[int(r)]

    for op, d, a, b, c, e in ins.tolist():
        name = _NAMES.get(op)
        if name not in _EMIT:
            return None
        if name == "sincos":  # writes d (sine) then b (cosine)
            x = rd(a)
            if x is None:
                return None
            body.append(f"big += abs({x}) > _BIG_ANGLE")
            s_, c_ = wr(d), wr(b)
            body.append(f"{s_}, {c_} = _sincos({x})")
            continue
        if name == "sincos_atan2":  # sin, cos of atan2(y = a, x = b) into d, c
            y, x = rd(a), rd(b)
            if y is None or x is None:
                return None
            r_ = f"w{count[0] + 1}"
            count[0] += 1
            body.append(f"{r_} = math.sqrt({x} * {x} + {y} * {y})")
            body.append(f"big += not (({r_} > 0.0) & ({r_} < np.inf))")
            s_ = wr(d)
            body.append(f"{s_} = {y} / {r_}")
            c_ = wr(c)
            body.append(f"{c_} = {x} / {r_}")
            continue
        if name == "clip":
            u, lo, hi = rd(a), rd(b), rd(c)
            if None in (u, lo, hi):
                return None
            t_ = f"w{count[0] + 1}"
            count[0] += 1
            body.append(f"{t_} = {u} if {u} >= {lo} else {lo}")
            out = wr(d)
            body.append(f"{out} = np.nan if ({u} != {u} or {lo} != {lo} or {hi} != {hi}) else "
                        f"({t_} if {t_} <= {hi} else {hi})")
            continue
        args = {"a": rd(a) if "{a}" in _BIN[name] else "", "b": rd(b) if "{b}" in _BIN[name] else "",
                "c": rd(c) if "{c}" in _BIN[name] else "", "e": rd(e) if "{e}" in _BIN[name] else ""}
        if None in args.values():
            return None
        expr = _BIN[name].format(**args)
        body.append(f"{wr(d)} = {expr}")
    lines = ["def loop(Rg, nb):", f"    R = carray(Rg, ({prog.n_reg * sub},))", "    big = 0",
             "    for ii in range(nb):"]
    lines += [f"        i{r} = R[{r * sub} + ii]" for r in loads]
    lines += [f"        {x}" for x in body]
    lines += [f"        R[{r * sub} + ii] = {v}" for r, v in sorted(cur.items()) if not v.startswith("i")]
    lines += ["    return 1 if big > 0 else 0"]
    return "\n".join(lines) + "\n"


def _module_text(body: str) -> str:
    here = Path(__file__).resolve().parent
    return ('"""A pose loop generated by parasynth.engine.posefn (do not edit)."""\n\n'
            "import math\n\n"
            + (here / "sincos.py").read_text()
            + "\n\nfrom numba import carray, cfunc, types\n\n"
            "@cfunc(types.int64(types.CPointer(types.float64), types.int64), cache=True, nogil=True, "
            "error_model=\"numpy\")\n"
            + body)


_LOCK = threading.Lock()
_LOADED: dict[str, object] = {}  # module path -> compiled loop (NONE: none to be had)
_HELPERS: dict[str, subprocess.Popen] = {}


def _enabled() -> bool:
    return os.environ.get("PARASYNTH_POSE_LOOPS", "1").strip() not in ("0", "off", "no", "false")


def _paths(prog: Program, sub: int):
    """(module path, done-marker path, module body) of ``prog``'s loop, or None."""
    folder = cache_dir()
    if folder is None:
        return None
    body = source(prog, sub)
    if body is None:
        return None
    # the numba and Python versions and numba's cache folder in the name: a module marked done
    # for another of them would have no compiled loop in this one's cache (and compile on load)
    stamp = f"{_VERSION}\n{sub}\n{numba.__version__}\n{sys.version_info[:2]}\n{os.environ.get('NUMBA_CACHE_DIR', '')}\n"
    key = hashlib.sha256(stamp.encode() + body.encode()).hexdigest()[:24]
    path = folder / "pose_loops" / f"pose_loop_{key}.py"
    return path, path.with_suffix(".done"), body


def _in_numba_cache(path: Path) -> bool:
    """Whether numba's cache holds the compiled loop of the module ``path`` (its index file, in
    ``__pycache__`` beside the module or under ``NUMBA_CACHE_DIR``): loading a module whose loop
    is not there would compile it in the calling process."""
    pattern = f"{path.stem}.loop-*.nbi"
    places = [path.parent / "__pycache__"]
    if os.environ.get("NUMBA_CACHE_DIR"):  # numba's folder for the modules of path's folder there
        places.append(Path(os.environ["NUMBA_CACHE_DIR"]) / numba_cache_subdir(str(path)))
    return any(next(p.glob(pattern), None) is not None for p in places if p.is_dir())


def _load(path: Path):
    name = path.stem
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # (numba's cache finds the module of a cached function by its name)
    try:
        spec.loader.exec_module(mod)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return mod.loop


_STATE: "weakref.WeakKeyDictionary[Program, list]" = weakref.WeakKeyDictionary()  # prog -> [loop, paths]


def function(prog: Program, sub: int):
    """The compiled pose loop of ``prog`` for sub-blocks of ``sub`` poses, or :data:`NONE`
    while there is none (see the module docstring: never compiles here)."""
    st = _STATE.get(prog)
    if st is not None and st[0] is not None:
        return st[0]
    if not _enabled():
        return NONE
    if st is None:
        found = _paths(prog, sub)
        st = _STATE[prog] = [NONE if found is None else None, found]
        if found is None:
            return NONE
    path, done, body = st[1]
    key = str(path)
    with _LOCK:
        fn = _LOADED.get(key)
        if fn is None:
            helper = _HELPERS.get(key)
            if done.exists() and (helper is None or helper.poll() is not None) and not _in_numba_cache(path):
                done.unlink(missing_ok=True)  # marked done, but numba's cache lost it: compile it again
            if done.exists() and (helper is None or helper.poll() is not None):
                try:
                    fn = _load(path)
                except Exception:  # a broken file or cache: the interpreter from now on
                    fn = NONE
                _LOADED[key] = fn
            elif helper is None:
                if not any(h.poll() is None for h in _HELPERS.values()):
                    _start(path, body)  # (one helper at a time: the others' programs on later calls)
            elif helper.poll() not in (None, 0):  # the helper failed: the interpreter from now on
                _LOADED[key] = fn = NONE
    if fn is None:
        return NONE
    st[0] = fn
    return fn


def build(prog: Program, sub: int):
    """Compile ``prog``'s pose loop in this process now and use it from now on (the loop, or
    :data:`NONE` when the program has none): for tests and benchmarks; a run never calls it."""
    found = _paths(prog, sub)
    if found is None:
        _STATE[prog] = [NONE, None]
        return NONE
    path, done, body = found
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists():
        path.write_text(_module_text(body))
    fn = _load(path)
    done.write_text("")
    with _LOCK:
        _LOADED[str(path)] = fn
    _STATE[prog] = [fn, found]
    return fn


def _lower_priority() -> None:  # the helper takes a core only when the run leaves one idle
    try:
        os.nice(10)
    except OSError:
        pass


def _start(path: Path, body: str) -> None:
    """Write the module and start its compiling helper (nothing if the folder cannot be
    written)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.exists():
            tmp = path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(_module_text(body))
            os.replace(tmp, path)
        _HELPERS[str(path)] = subprocess.Popen(
            [sys.executable, "-m", "parasynth.engine.posefn", str(path)],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            preexec_fn=_lower_priority if hasattr(os, "nice") else None)
    except OSError:
        _LOADED[str(path)] = NONE


def main(argv=None) -> int:
    """``python -m parasynth.engine.posefn FILE...``: compile each generated module into numba's
    cache and mark it done. Each compile is held (:func:`parasynth.engine.held.hold`, a
    ``.held`` file beside the module): a helper of another process compiling the same module
    is waited for instead of compiled beside (its loop is then in the cache)."""
    for name in (sys.argv[1:] if argv is None else argv):
        path = Path(name)
        done, mark = path.with_suffix(".done"), path.with_suffix(".held")
        while not held.hold(mark):
            held.wait_let_go(mark)
            if done.exists():
                break
        else:
            try:
                _load(path)
                done.write_text("")
            finally:
                held.let_go(mark)
    return 0


if __name__ == "__main__":  # pragma: no cover - the helper process
    raise SystemExit(main())
