"""Compiling the engine up front, saying so, and staying interruptible while it compiles.

numba compiles a kernel the first time it is called with new argument types and keeps the
machine code in its cache (``NUMBA_CACHE_DIR``, by default next to the sources), so a new
installation compiles once and later processes load the kernels in well under a second. A
cold compile takes tens of seconds, during which a caller would otherwise see nothing, charge
the time to whatever it was timing, and could not be interrupted (numba's LLVM calls come
back through ctypes, where a ``KeyboardInterrupt`` is printed as "Exception ignored" and
dropped).

:func:`warm_up` runs the work that needs the kernels -- any callable that evaluates with the
engine, typically one design of a study, or :func:`exercise` for a mechanism -- on a separate
thread while the calling thread waits in short, interruptible steps:

* if numba starts compiling (a ``numba:compile`` event: a kernel not in the cache; loading
  from the cache raises none), ``progress`` receives "compiling the evaluation engine (once
  per installation) ..." at once, then the elapsed time and the kernel being compiled every
  few seconds, then the total; with a warm cache it receives nothing;
* a ``KeyboardInterrupt`` in the calling thread, or ``stop()`` becoming true, ends the wait at
  once: the compiling thread is a daemon and is abandoned (what it finished is in the cache).
  A process that then ends while that thread is still inside LLVM would tear LLVM down under it
  at the interpreter's shutdown (an LLVM assertion or a segmentation fault instead of the exit
  status): :func:`abandoned` tells, and the ``parasynth`` program ends such a process at once
  with its status once its output is flushed and its helpers stopped
  (:func:`parasynth.cli.entry`); a script of one's own can do the same (``os._exit``).

:func:`reference` is the other way of not waiting: inside it every entry point evaluates with
the NumPy reference (the same answers to ~1e-12), for work too small to repay compiling.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time

from ..common.processes import compile_ahead_off

__all__ = ["warm_up", "WarmUp", "COMPILING", "abandoned", "compile_ahead_off"]



#: The compiling threads of :func:`warm_up` (see :func:`abandoned`).
_THREADS: list = []


def abandoned() -> bool:
    """Whether a compiling thread of :func:`warm_up` whose wait was ended (an interrupt,
    ``stop``) is still running: numba is compiling on it, and the interpreter's shutdown must
    not tear LLVM down under it (see the module docstring)."""
    _THREADS[:] = [t for t in _THREADS if t.is_alive()]
    return bool(_THREADS)

#: What ``progress`` receives first when the kernels are being compiled.
COMPILING = "compiling the evaluation engine (once per installation) ..."

# Readable names of the kernels, for the progress messages.
_NAMES = {
    "_feasible_kernel": "feasibility kernel",
    "_margins_kernel": "constraint-margin kernel",
    "_pose_kernel": "pose kernel",
    "_run": "expression interpreter",
    "_pose_prog": "pose program",
    "_margin_kernel": "singularity-margin kernel",
    "_lti_kernel": "transmission-index kernel",
    "_kappa_kernel": "condition-number kernel",
    "_dir_kernel": "leg-direction kernel",
    "_constraint_rank_kernel": "constraint-rank kernel",
    "helper processes": "kernels compiled in helper processes",
}


class WarmUp:
    """The outcome of :func:`warm_up`: ``done`` (the work finished; False when interrupted
    or stopped), ``compiled`` (numba compiled something), ``seconds`` (wall time of the
    work), ``compile_seconds`` (from the first compile event to the end of the work, 0 when
    nothing was compiled), ``kernels`` (the functions compiled), ``error`` (an exception of
    the work, which warm_up does not raise: the real evaluation meets it again)."""

    def __init__(self):
        self.done = False
        self.compiled = False
        self.seconds = 0.0
        self.compile_seconds = 0.0
        self.kernels: list[str] = []
        self.error: BaseException | None = None
        self.result = None
        self._first = None
        self._current = None

    def __bool__(self):
        return self.done

    def __repr__(self):
        return (f"WarmUp(done={self.done}, compiled={self.compiled}, seconds={self.seconds:.2f}, "
                f"compile_seconds={self.compile_seconds:.2f}, kernels={len(self.kernels)})")


def _listener(state: WarmUp, base):
    """A numba listener of ``numba:compile`` events (cache misses only) updating ``state``."""

    class Listener(base):
        depth = 0

        def on_start(self, event):
            if state._first is None:
                state._first = time.perf_counter()
            state.compiled = True
            if self.depth == 0:
                state._current = _name(event)
            self.depth += 1

        def on_end(self, event):
            self.depth = max(0, self.depth - 1)
            state.kernels.append(_name(event))
            if self.depth == 0:
                state._current = None

    return Listener()


def _name(event) -> str:
    return getattr(getattr(event.data.get("dispatcher"), "py_func", None), "__name__", "?")


def _stderr(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def warm_up(work, *, progress=_stderr, stop=None, poll: float = 0.1, every: float = 5.0, busy=None,
            announced: bool = False, since: float | None = None) -> WarmUp:
    """Run ``work()`` on a compiling thread and wait for it interruptibly (see the module
    docstring); returns a :class:`WarmUp` (true when the work finished).

    ``work``: a callable (its result is ``WarmUp.result``); ``parasynth.engine.warm_up`` also
    takes a mechanism, which it exercises (``parasynth.engine.exercise``). ``progress``: a
    callable receiving one message string at a time
    (default: printed on stderr), or None for silence; it is called only when numba
    compiles. ``stop``: a callable polled every ``poll`` seconds; when it returns true the
    wait ends (``done`` False). A ``KeyboardInterrupt`` in the calling thread propagates at
    once. ``busy``: a callable, true while other processes compile kernels the work waits for
    (:func:`parasynth.engine.precompile.start_early`): that wait is reported as a compile.
    ``announced``: :data:`COMPILING` was said already (when those processes were started), so
    the progress goes on with the elapsed time; ``since``: when that compile started
    (``time.perf_counter``), from which the elapsed time and ``compile_seconds`` count.
    Calls from a thread other than the main one run ``work`` directly (nothing to keep
    interruptible there)."""
    state = WarmUp()
    t0 = time.perf_counter()
    state._first = since  # None: from the first compile event (or the first busy poll)
    try:
        from numba.core import event as _ev
    except Exception:  # pragma: no cover - no numba: nothing compiles
        _ev = None
    if _ev is not None:
        listener = _listener(state, _ev.Listener)
        _ev.register("numba:compile", listener)
    box = {}

    def body():
        try:
            box["result"] = work()
        except BaseException as e:  # noqa: BLE001 - reported in the outcome
            box["error"] = e

    try:
        if threading.current_thread() is not threading.main_thread():
            body_thread = None
            body()
        else:
            body_thread = threading.Thread(target=body, name="parasynth-engine-compile", daemon=True)
            body_thread.start()
            _THREADS.append(body_thread)
        said = announced
        last = time.perf_counter()
        while body_thread is not None and body_thread.is_alive():
            body_thread.join(poll)
            if busy is not None and not state.compiled and busy():
                state.compiled = True
                if state._first is None:
                    state._first = time.perf_counter()
                state._current = "helper processes"
            if state.compiled and progress is not None:
                now = time.perf_counter()
                if not said:
                    progress(COMPILING)
                    said, last = True, now
                elif now - last >= every:
                    cur = state._current
                    what = f" ({_NAMES.get(cur, cur)})" if cur else ""
                    progress(f"  ... {now - state._first:.0f} s{what}")
                    last = now
            if stop is not None and body_thread.is_alive() and stop():
                break
        state.done = "result" in box or "error" in box
        state.result = box.get("result")
        state.error = box.get("error")
        state.seconds = time.perf_counter() - t0
        if state.compiled and state._first is not None:
            state.compile_seconds = time.perf_counter() - state._first
        if state.done and state.compiled and progress is not None:
            progress(f"  compiled in {state.compile_seconds:.1f} s (cached for later runs)")
        return state
    finally:
        if _ev is not None:
            with contextlib.suppress(Exception):
                _ev.unregister("numba:compile", listener)
