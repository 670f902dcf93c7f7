"""The evaluation engine: feasibility, constraint margins and poses of batches of poses,
compiled from what a mechanism description declares, with the NumPy methods of
:class:`~parasynth.model.mechanism.Mechanism` as the reference.

Entry points (``engine="compiled"`` is the default everywhere; ``"numpy"`` the reference):

* :func:`feasible` ``(mech, X, names=None, engine=...)`` -> (N,) bool, as
  ``Mechanism.is_feasible``;
* :func:`feasible_extents` ``(mech, X, names=None, engine=...)`` -> ``(ok (N,), lo (3,),
  hi (3,))``: :func:`feasible` and the least / greatest platform position over the feasible
  poses from one kernel pass (what ``workspace`` records), or None where that pass is not
  the whole answer (the caller then asks :func:`feasible` and :func:`pose_batch`);
* :func:`margins` ``(mech, X, names=None, engine=...)`` -> {name: (N,)}, as
  ``Mechanism.constraint_margins``;
* :func:`pose_batch` ``(mech, X, twist=False)`` -> ``(valid (N,), p (N, 3), R (N, 3, 3), T)``
  with T (N, 6, n_task) the twist map when ``twist`` (else None), as ``mech.pose_valid``,
  ``mech.pose``, ``mech.twist_map`` (p, R, T are those of the home pose where not valid,
  like the NumPy methods evaluated on home-substituted poses -- here they are simply not
  meaningful: use ``valid``);
* :func:`available` ``(mech, names=None)`` and :func:`reason` ``(mech, names=None)``: whether
  the compiled path covers ``mech`` and, if not, why;
* the compiled pose-wise indices (:mod:`parasynth.engine.indices`): :func:`use_compiled`
  ``(mech, engine, what)`` says whether they cover ``mech`` (and, once, why not), then
  :func:`singularity_margin`, :func:`transmission`, :func:`condition_number`,
  :func:`leg_directions`, :func:`constraint_rank` evaluate them;
* :func:`warm_up` ``(work, progress=..., stop=...)``: run ``work`` (one design, or
  :func:`exercise` of a mechanism) on a compiling thread, saying "compiling the evaluation
  engine (once per installation) ..." only when numba actually compiles, and staying
  interruptible (see :mod:`parasynth.engine.warmup`);
* :func:`reference` (a context manager, :func:`parasynth.common.validation.numpy_reference`): inside
  it every entry point evaluates with the NumPy reference, ``engine="compiled"`` requests
  included -- for work too small to repay compiling (``parasynth validate``).

How it works: :mod:`parasynth.engine.program` translates the task parametrisation and the
expression margins into a register program (parameters as a constants vector, so one program
serves every design of a description); :mod:`parasynth.engine.core` holds the plans (leg
geometry and limits as arrays, read for every mechanism) and the numba kernels that interpret
the program per sub-block of poses and run the legs' inverse kinematics and checks;
:mod:`parasynth.engine.evaluate` runs them on pose batches.

Layering: the engine imports the NumPy model (:mod:`parasynth.model.mechanism`, legs, constraints)
and never the mechanism descriptions; described mechanisms
(:class:`~parasynth.mechanisms.description.DescribedMechanism`) call these entry points from
their ``is_feasible``, ``constraint_margins``, ``singularity_margin`` and
``structural_constraint_rank``. This package itself imports only NumPy: the modules holding
the numba kernels (``core``, ``evaluate``, ``indices``) are loaded at the first compiled
evaluation, so ``import parasynth`` does not import numba. ``HAVE_NUMBA``, ``BLOCK``, ``SUB``,
``KernelPlan`` and ``Unsupported`` are looked up in :mod:`parasynth.engine.core` on first use.

Anything the compiled path does not handle -- a model class that is not a description, a leg
or constraint type it does not know, an expression construct it cannot translate, a
translation that does not reproduce ``mech.pose`` on probe poses, numba missing (or
``PARASYNTH_NO_NUMBA`` set) -- runs on NumPy, and says so once per mechanism kind and reason
(a :class:`EngineFallbackWarning` naming the construct, also logged on the
``parasynth.engine`` logger). The answer is never a different one silently.
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import os
import sys
import warnings

import numpy as np

from ..model.constraints import SingularityMarginFloor
from ..model import parasitic as _parasitic
from ..model.mechanism import EngineFallbackWarning
from ..common.validation import ENGINES, check_engine
from ..common.validation import numpy_reference as reference
from . import warmup as _warmup
from .warmup import COMPILING, WarmUp, compile_ahead_off

__all__ = ["HAVE_NUMBA", "ENGINES", "EngineFallbackWarning", "feasible", "feasible_extents", "margins", "pose_batch",
           "solved_unknowns", "available",
           "reason", "check_engine", "plan", "use_compiled", "warn_fallback", "coverage", "singularity_margin",
           "transmission", "local_transmission_index", "condition_number", "leg_directions", "constraint_rank", "ready",
           "closure_plan", "closure_prep", "closure_solve", "warm_up", "exercise", "needs", "effective_engine", "WarmUp", "COMPILING", "reference",
           "compiling_early", "announce_compile", "compile_ahead_off", "n_threads"]

#: Names looked up in :mod:`parasynth.engine.core` when first asked for.
_CORE_NAMES = ("HAVE_NUMBA", "BLOCK", "SUB", "KernelPlan", "Unsupported")


_MODULES: tuple | None = None


def _compiled():
    """The modules of the compiled path, ``(core, evaluate, indices, precompile, closure, chains)``."""
    global _MODULES
    if _MODULES is None:
        # lazy: they import numba (about a second) and define its kernels: loaded at the first
        # compiled evaluation (then kept: an import statement at every call cost ~4 us)
        from . import chains, closure, core, evaluate, indices, precompile

        _MODULES = (core, evaluate, indices, precompile, closure, chains)
    return _MODULES


def _closure():
    """:mod:`parasynth.engine.closure`."""
    return _compiled()[4]


#: While :func:`needs` runs: the set receiving the compiled entry points asked for.
_WANTED: contextvars.ContextVar = contextvars.ContextVar("parasynth_engine_wanted", default=None)

#: ``use_compiled``'s ``what`` -> the entry point (a name of :data:`EXERCISES`).
_WHAT_KIND = {"singularity_margin": "singularity_margin", "constraint rank": "constraint_rank",
              "pressure_angle_indices": "leg_directions", "output_transmission_index": "transmission",
              "local_transmission_index": "transmission", "local_condition_number": "condition_number"}


def _engine_for(kind: str, engine) -> str:
    """``check_engine(engine)``, and inside :func:`needs`: "numpy", having recorded that the
    compiled entry point ``kind`` was asked for."""
    eng = check_engine(engine)
    wanted = _WANTED.get()
    if wanted is not None and eng == "compiled":
        wanted.add(kind)
        return "numpy"
    return eng


def effective_engine(engine) -> str:
    """The engine that answers a request for ``engine``: "numpy" inside :func:`reference` and
    :func:`needs`, else ``check_engine(engine)`` (for keys of cached results)."""
    eng = check_engine(engine)
    return "numpy" if _WANTED.get() is not None else eng


def __getattr__(name):
    if name in _CORE_NAMES:
        return getattr(_compiled()[0], name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# ---------------------------------------------------------------------------------------------
# feasibility, margins, poses
# ---------------------------------------------------------------------------------------------
def plan(mech, names=None):
    """(KernelPlan or None, reason or None) for ``mech`` and the constraints ``names``."""
    return _compiled()[1].plan(mech, names)


def available(mech, names=None) -> bool:
    """Whether the compiled path covers ``mech`` (with the constraints ``names``)."""
    return _compiled()[1].available(mech, names)


def reason(mech, names=None) -> str | None:
    """Why the compiled path does not cover ``mech`` (None if it does)."""
    return _compiled()[1].reason(mech, names)


def _floor_margin(mech, X) -> np.ndarray:
    """The singularity margin of poses ``X`` for a :class:`SingularityMarginFloor` constraint:
    the compiled index kernel, or NumPy (said once) where it does not cover ``mech``."""
    if use_compiled(mech, "compiled", "singularity_margin"):
        return singularity_margin(mech, X)
    return mech.singularity_margin(X, engine="numpy")


def _chains_asked(mech) -> None:
    """Inside :func:`needs`: a mechanism with chain limbs also asks for their kernels (the
    compiled inverse kinematics and index rows, ``"chains"``)."""
    wanted = _WANTED.get()
    if wanted is not None and any(callable(getattr(leg, "chain_arrays", None)) for leg in getattr(mech, "legs", ())):
        wanted.add("chains")


def _floors_asked(mech, names) -> None:
    """Inside :func:`needs`: a selection with a singularity-margin floor also asks for the
    singularity-margin kernel (the compiled path applies the floor with it)."""
    wanted = _WANTED.get()
    if wanted is not None:
        try:
            if any(isinstance(c, SingularityMarginFloor) for c in mech._select(names)):
                wanted.add("singularity_margin")
        except (ValueError, TypeError, AttributeError):
            pass  # unknown names: the reference raises


def feasible(mech, X, names=None, engine: str = "compiled"):
    """(N,) bool: reachable and every selected constraint satisfied at poses ``X`` -- the
    answer of ``mech.is_feasible(X, names, engine="numpy")`` (see the agreement contract in
    :mod:`parasynth.engine.core`). A single pose (n_task,) gives a scalar bool. A
    :class:`~parasynth.model.constraints.SingularityMarginFloor` is applied after the feasibility
    kernel, with the compiled singularity margin of the poses it accepts."""
    if _engine_for("feasible", engine) == "numpy":
        _floors_asked(mech, names)
        _chains_asked(mech)
        return mech._is_feasible_numpy(X, names)
    return _compiled()[1].feasible(mech, X, names, _floor_margin)


def feasible_extents(mech, X, names=None, engine: str = "compiled"):
    """``(ok (N,) bool, lo (3,), hi (3,))``: :func:`feasible` of the poses ``X`` (N, n_task)
    and the least and greatest platform position (x, y, z) over the feasible ones (as
    :func:`pose_batch` gives them; +inf / -inf when none is feasible), from one pass of the
    feasibility kernel; or None when that pass does not answer for ``mech`` (the NumPy
    engine, no compiled plan, a view of another mechanism's parametrisation, a
    singularity-margin floor): the caller then asks :func:`feasible` and :func:`pose_batch`."""
    if getattr(mech, "pose_mechanism", None) is not None or "is_feasible" in vars(mech):
        return None
    if _engine_for("feasible", engine) == "numpy" or not _feasible_is_engines(type(mech)):
        return None
    return _compiled()[1].feasible_extents(mech, X, names)


#: The module whose ``is_feasible`` is this engine's :func:`feasible` (a mechanism description's).
_ENGINE_FEASIBLE_MODULE = "parasynth.mechanisms.description.mechanism"


@functools.lru_cache(maxsize=64)
def _feasible_is_engines(cls) -> bool:
    """Whether ``cls.is_feasible`` is a mechanism description's (which answers with
    :func:`feasible`), not one a subclass replaced with other checks: only then may one
    feasibility pass stand for it."""
    for c in cls.__mro__:
        f = c.__dict__.get("is_feasible")
        if f is not None:
            return getattr(f, "__module__", None) == _ENGINE_FEASIBLE_MODULE
    return False


def margins(mech, X, names=None, engine: str = "compiled") -> dict:
    """{constraint name: (N,) margin} as ``mech.constraint_margins(X, names, engine="numpy")``
    (-inf where a leg cannot reach the pose or a margin is undefined)."""
    if _engine_for("margins", engine) == "numpy":
        _floors_asked(mech, names)
        _chains_asked(mech)
        return mech._constraint_margins_numpy(X, names)
    return _compiled()[1].margins(mech, X, names, _floor_margin)


def pose_batch(mech, X, twist: bool = False, engine: str = "compiled"):
    """``(valid, p, R, T)`` of poses X (N, n_task): validity of the parametrisation (as
    ``mech.pose_valid``), platform positions (N, 3), rotations (N, 3, 3) and, with ``twist``,
    the twist map (N, 6, n_task) (as ``mech.twist_map``; else None). Entries of invalid
    poses are unspecified. A mechanism with a ``pose_mechanism`` (a view of another one's
    parametrisation) is answered by that one."""
    src = getattr(mech, "pose_mechanism", None)
    if src is not None:  # a view whose parametrisation is another mechanism's (parasynth.measures.robustness.AsBuilt)
        return pose_batch(src, X, twist, engine)
    Xa, _ = mech._poses(X)
    if _engine_for("twist" if twist else "pose", engine) == "compiled":
        out = _compiled()[1].compiled_pose_batch(mech, Xa, twist)
        if out is not None:
            return out
    with np.errstate(all="ignore"):
        valid = mech.pose_valid(Xa)
        Xs = np.where(valid[:, None], Xa, mech.home)
        P, R = mech.pose(Xs)
        T = mech.twist_map(Xs) if twist else None
    return valid, np.asarray(P, dtype=float), np.asarray(R, dtype=float), T


def solved_unknowns(mech, X, engine: str = "compiled"):
    """``(valid (N,), U (N, m))``: the unknowns of a description's ``task.solve`` (its
    dependent, parasitic coordinates) at poses X (N, n_task) by the compiled solve -- the
    values ``mech.solved_unknowns`` gives to the solve's tolerance (both iterate Gauss-Newton
    from the home solution; the compiled one takes its fixed number of steps) -- or None when
    the compiled path does not answer (the NumPy engine, no ``task.solve``, a program the
    engine does not cover). Entries of invalid poses are unspecified."""
    if getattr(mech, "pose_mechanism", None) is not None:
        return None
    Xa, _ = mech._poses(X)
    if _engine_for("pose", engine) != "compiled":
        return None
    return _compiled()[1].compiled_unknowns(mech, Xa)


# ---------------------------------------------------------------------------------------------
# compiled pose-wise indices (parasynth.engine.indices)
# ---------------------------------------------------------------------------------------------
def coverage(mech) -> tuple[bool, str]:
    """``(True, "")`` when the compiled indices cover ``mech``, else ``(False, reason)``."""
    return _compiled()[2].coverage(mech)


def warn_fallback(what: str, mech, reason: str) -> None:
    """Say once per (what, model class, reason) that ``what`` runs on NumPy and why."""
    _compiled()[0].warn_fallback(what, mech, reason, stacklevel=5)


def use_compiled(mech, engine, what: str) -> bool:
    """Whether ``what`` runs on the compiled index kernels for ``mech``: ``engine`` is
    "compiled" or "numpy" (``ValueError`` otherwise); "compiled" falls back to NumPy, saying
    why once, when the kernels do not cover the mechanism."""
    if _engine_for(_WHAT_KIND.get(what, what), engine) == "numpy":
        _chains_asked(mech)
        return False
    ei = _compiled()[2]
    ok, why = ei.coverage(mech)
    if not ok:
        ei.warn_fallback(what, mech, why)
    return ok


#: Entry points found ready (:func:`ready`): their kernels compiled here or in numba's cache.
_READY: set = set()
#: Entry points found not ready in numba's cache on disk (read once per process).
_NOT_CACHED: set = set()


def ready(kind: str) -> bool:
    """Whether every kernel of the compiled entry point ``kind`` (a name of :data:`EXERCISES`)
    is compiled in this process or in numba's cache, so that calling it compiles nothing. The
    cache on disk is read once per process for each ``kind``; a kernel compiled later in this
    process counts from then on."""
    if kind in _READY:
        return True
    core, pre = _compiled()[0], _compiled()[3]
    if not core.HAVE_NUMBA:
        return False
    names = pre.KERNELS_OF.get(kind, ())
    sigs = pre.signatures()
    if kind in _NOT_CACHED:
        ok = all(n in sigs and sigs[n][0].signatures for n in names)
    else:
        ok = not pre.missing([kind])
        if not ok:
            _NOT_CACHED.add(kind)
    if ok:
        _READY.add(kind)
    return ok


def singularity_margin(mech, X) -> np.ndarray:
    """Compiled :meth:`Mechanism.singularity_margin` (N,) (see :func:`use_compiled`)."""
    return _compiled()[2].singularity_margin(mech, X)


def singularity_margin_at(legs, p, R, n_actuators: int, constraint_rank: int, length_scale: float):
    """Compiled singularity margin (N,) of ``legs`` at explicit platform poses (p, R), or None
    when a leg has no compiled form (the caller evaluates it on NumPy); see
    :func:`parasynth.engine.indices.singularity_margin_at`."""
    if _engine_for("singularity_margin", "compiled") != "compiled":
        return None
    ei = _compiled()[2]
    try:
        return ei.singularity_margin_at(legs, p, R, n_actuators, constraint_rank, length_scale)
    except ei._Unsupported:
        return None


def closure_residuals(legs, p, R, length_scale: float, engine: str = "compiled"):
    """:func:`parasynth.model.parasitic.closure_residuals` (N, k) of ``legs`` at platform poses
    (p, R), the closure equations of chain limbs (:class:`parasynth.model.chains.ChainLeg`) by
    the compiled solve of :func:`parasynth.engine.chains.closure_residuals` (the same
    branch-following warm start; NumPy without numba, with ``engine="numpy"`` and inside
    :func:`reference`)."""
    if _engine_for("chain_closure", engine) == "compiled" and any(callable(getattr(leg, "chain_arrays", None))
                                                                  for leg in legs):
        return _compiled()[5].closure_residuals(legs, p, R, length_scale)
    return _parasitic.closure_residuals(legs, p, R, length_scale)


def closure_plan(leg_sets, fields=None):
    """The compiled closure plan (:class:`parasynth.engine.closure.ClosurePlan`) of ``leg_sets``
    (draws of legs of the same types), or None when the compiled closure does not cover them
    (a leg type without one, numba missing, inside :func:`reference`; ``fields``: the draws'
    geometry stacked per leg, {field: (draws, ...)}, when the caller has it): the caller then solves
    the closure on NumPy (:func:`parasynth.measures.accuracy.closure_residuals`)."""
    if _engine_for("closure", "compiled") != "compiled":
        return None
    try:
        return _closure().plan(leg_sets, fields)
    except _compiled()[2]._Unsupported:
        return None


def closure_prep(cp, p, R, length_scale: float, draw=None, jacobian: bool = True):
    """Closure residuals, their pose Jacobian (with ``jacobian``) and reachability at explicit
    poses (:func:`parasynth.engine.closure.prep`) of a plan from :func:`closure_plan`."""
    return _closure().prep(cp, p, R, length_scale, draw, jacobian)


def closure_solve(cp, p0, R0, Gi, h0, ok, dq, scale, src, draw, max_iter: int = 20):
    """The actual poses of perturbed legs by chord Newton (:func:`parasynth.engine.closure.solve`)
    of a plan from :func:`closure_plan`."""
    return _closure().solve(cp, p0, R0, Gi, h0, ok, dq, scale, src, draw, max_iter)


def constraint_rank(mech, X=None) -> int:
    """Compiled :meth:`Mechanism.structural_constraint_rank` at pose ``X`` (default ``home``)."""
    return _compiled()[2].constraint_rank(mech, X)


def transmission(mech, X, rtol: float = 1e-9):
    """Compiled input (N, n_act), output (N, n_act) and local (N,) transmission indices."""
    return _compiled()[2].transmission(mech, X, rtol)


def local_transmission_index(mech, X, rtol: float = 1e-9) -> np.ndarray:
    """Compiled local transmission index (N,)."""
    return _compiled()[2].local_transmission_index(mech, X, rtol)


def condition_number(mech, X, length: float | None = None) -> np.ndarray:
    """Compiled task-space condition number (N,) of :func:`parasynth.measures.indices.local_condition_number`."""
    return _compiled()[2].condition_number(mech, X, length)


def leg_directions(mech, X) -> tuple[np.ndarray, np.ndarray]:
    """Compiled unit leg directions (N, n_legs, 3) and reachability (N,)."""
    return _compiled()[2].leg_directions(mech, X)


# ---------------------------------------------------------------------------------------------
# compiling ahead of the work
# ---------------------------------------------------------------------------------------------
#: What :func:`exercise` may compile.
EXERCISES = ("feasible", "margins", "pose", "twist", "singularity_margin", "transmission", "condition_number",
             "leg_directions", "constraint_rank", "closure")


def exercise(mech, what=EXERCISES) -> None:
    """Call the engine's entry points named in ``what`` (see :data:`EXERCISES`) for ``mech``
    on its home pose, so that the kernels they use are compiled (or loaded from the cache).
    A mechanism the engine does not cover runs on NumPy, as it would later."""
    X = np.asarray(mech.home, dtype=float)[None, :]
    what = set(what)
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        if "feasible" in what:
            feasible(mech, X)
            if effective_engine("compiled") == "compiled":
                _compiled()[0].spin_warm()  # the threads' waits (core._spin_done, core._crew_spin), used by large batches
        if "margins" in what:
            margins(mech, X)
        if "pose" in what:
            pose_batch(mech, X)
        if "twist" in what:
            pose_batch(mech, X, twist=True)
        idx = what & {"singularity_margin", "transmission", "condition_number", "leg_directions", "constraint_rank"}
        if idx:
            ok, _ = coverage(mech)
            if not ok:
                return
            calls = {"singularity_margin": singularity_margin, "transmission": transmission,
                     "condition_number": condition_number, "leg_directions": leg_directions,
                     "constraint_rank": lambda m, _X: constraint_rank(m)}
            for name in sorted(idx):
                with contextlib.suppress(ValueError):  # constraint_rank: home unreachable
                    calls[name](mech, X)
        if "closure" in what:
            cp = closure_plan([mech.legs])
            if cp is not None:
                p, R = mech._pose(X)
                h0, _, ok = closure_prep(cp, p, R, mech.length_scale)
                closure_solve(cp, p, R, np.zeros((1, 6, cp.m)), h0, ok, np.zeros(cp.m), np.ones(cp.m),
                              np.zeros(1, np.int64), np.zeros(1, np.int64))


def needs(work) -> set:
    """The compiled entry points (names of :data:`EXERCISES`) that ``work()`` asks for: it
    runs once, each of those entry points answering with the NumPy reference (nothing is
    compiled); its result and any exception are discarded. Work inside :func:`reference`
    asks for none."""
    wanted: set = set()
    token = _WANTED.set(wanted)
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            try:
                work()
            except Exception:  # noqa: BLE001 - what it asked for before failing is recorded
                pass
    finally:
        _WANTED.reset(token)
    return wanted


def n_threads() -> int:
    """The threads the engine spreads a batch over (:func:`parasynth.engine.core.n_threads`:
    numba's thread count, i.e. ``NUMBA_NUM_THREADS`` or the cores, which a study's worker
    processes share out), without importing numba when the kernels are not loaded yet."""
    core = sys.modules.get(__name__ + ".core")
    if core is not None:
        return core.n_threads()
    try:
        return max(1, int(os.environ.get("NUMBA_NUM_THREADS", "")))
    except ValueError:
        return os.cpu_count() or 1


def compiling_early() -> bool:
    """Whether helper processes started ahead of the work
    (:func:`parasynth.engine.precompile.start_early`) are still compiling: they hold cores that
    other parallel work of this process (the enumeration of a study's structures) should leave
    to them."""
    pre_mod = sys.modules.get(__name__ + ".precompile")  # loaded if start_early ran
    return pre_mod is not None and any(pre_mod.early().values())


#: The compile notice (:data:`COMPILING`) was said ahead of the next :func:`warm_up` (see
#: :func:`announce_compile`).
_ANNOUNCED = False


def announce_compile() -> bool:
    """Whether the compile cache lacks the pose kernel, which every compiled evaluation uses (an
    installation that has not compiled yet): then the next :func:`warm_up` compiles, and takes
    the notice as said, going on with the elapsed time. The study runner calls it just before
    its warm-up, to say :data:`COMPILING` at once instead of after the warm-up's first steps
    (the work run once on NumPy to learn what it needs, numba's import). False without numba, with
    ``PARASYNTH_COMPILE_AHEAD=0``, when the pose kernel is cached, or when helpers started
    ahead (:func:`parasynth.engine.precompile.start_early`) said it already."""
    global _ANNOUNCED
    if compile_ahead_off():
        return False
    core, pre = _compiled()[0], _compiled()[3]
    if not core.HAVE_NUMBA or pre.early() or pre.in_cache("_pose_kernel"):  # early helpers: said when started
        return False
    _ANNOUNCED = True
    return True


def _ahead(work):
    """The kernels to compile ahead of ``work`` (:mod:`parasynth.engine.precompile`): none
    when the pose
    kernel, which every compiled evaluation uses, is already in the cache (an installation
    that compiled before: ``work`` compiles what it still needs itself); with the kernels in
    the queues of the helpers of :func:`parasynth.engine.precompile.start_early` (the work
    claims those they have not begun), or, without such early helpers, those its entry points
    use besides (``precompile.WITH``). Off with
    ``PARASYNTH_COMPILE_AHEAD=0``. The kernels early helpers are still compiling are among them
    whether ``work``'s first evaluation asks for them or not: they were started for this work
    (the structural constraint rank of :data:`~parasynth.engine.precompile.STUDY`, which a design
    asks for only once compiled), so the warm-up waits for them rather than stopping them half
    done, which left a run whose other kernels were cached on NumPy for that entry point, run
    after run."""
    pre = _compiled()[3]
    running = [n for n, busy in pre.early().items() if busy]
    if pre.in_cache("_pose_kernel") and not running:
        return []
    kinds = needs(work)
    wanted = pre.missing(kinds)
    if not pre.early():  # a run compiling on its own: what its entry points use besides (precompile.WITH)
        wanted += [n for n in pre.with_kernels(kinds) if n not in wanted]
    # and what start_early's helpers have in their queues for it
    return wanted + [n for n in dict.fromkeys(running) if n not in wanted]


def warm_up(work, processes: int | None = None, **options) -> WarmUp:
    """:func:`parasynth.engine.warmup.warm_up` of ``work``: a callable, or a mechanism, which is
    :func:`exercise`\\ d on its home pose. On an empty compile cache the kernels ``work``
    needs (:func:`needs`) are first compiled side by side in ``processes`` processes (default:
    the number of cores; see :mod:`parasynth.engine.precompile`); ``work`` then loads them."""
    if not callable(work):
        mech = work

        def work():
            return exercise(mech)

    if compile_ahead_off():
        return _warmup.warm_up(work, **options)
    loaded = []
    # helpers started ahead of the work (precompile.start_early) still compiling: the wait for
    # them is a compile too (progress is said); nothing to ask when none were started
    pre_mod = sys.modules.get(__name__ + ".precompile")  # loaded if start_early ran
    if pre_mod is not None and pre_mod.early():
        options.setdefault("busy", lambda: any(pre_mod.early().values()))
        options.setdefault("announced", True)  # said when they were started
        options.setdefault("since", pre_mod.started_at())  # and the compile's time counts from then
    global _ANNOUNCED
    if _ANNOUNCED:  # said by the command (announce_compile): the progress goes on from there
        _ANNOUNCED = False
        options.setdefault("announced", True)

    def compile_then_work():
        # on the compiling thread: importing numba (about a second) included
        core, _, _, pre = _compiled()[:4]
        loaded.append(pre)
        ahead = _ahead(work) if core.HAVE_NUMBA else []
        if ahead:
            pre.compile_ahead(ahead, processes)
            _NOT_CACHED.clear()  # ready() reads the cache again: those kernels are in it now
        return work()

    try:
        return _warmup.warm_up(compile_then_work, **options)
    finally:
        for pre in loaded:
            pre.stop_helpers()  # interrupted or stopped while they compile
