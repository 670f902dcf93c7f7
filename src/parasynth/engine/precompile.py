"""Compiling the kernels a run needs in several processes at once, ahead of the run.

A cold compile of the kernels one study uses takes tens of seconds of CPU, nearly all of it
in one kernel at a time (numba holds one compiler lock per process). The kernels are
independent, and numba's cache (``NUMBA_CACHE_DIR``) is a set of files safe to write from
several processes, so they can be compiled side by side: :func:`compile_ahead` compiles the
interpreter kernels (pose, feasibility, margins: they share the expression interpreter) in
this process and hands the index kernels to helper processes (``python -m
parasynth.engine.precompile NAME ...``), which compile them by their signature
(:func:`parasynth.engine.core.signatures`) into the same cache; when it returns, every kernel
it was given is in the cache and the real work loads them (well under a second).

Which kernels: the work is first run once on the NumPy reference, recording the compiled
entry points it asks for (:func:`parasynth.engine.needs`), which :data:`KERNELS_OF` maps to
kernels. Only kernels not yet in the cache are compiled; with the pose kernel in the cache
(an installation that compiled before) nothing of this runs and the work compiles what it
still needs itself, as it would without this module. A helper that fails costs nothing but
time: the work then compiles the kernel itself.

Work with something else to do first (a structure study enumerates its structures, several
seconds on one core) can start the helpers earlier, :func:`start_early` with the entry points
it will need (:data:`STRUCTURE_STUDY`): one helper is given all of them in a queue, longest
first, and claims each before it compiles it (a file made in a folder of its own, which only one
process can make); :func:`compile_ahead`, once the work gets to it, claims the kernels of that
queue the helper has not begun, in the same order, compiles them in its own process, and waits
for the others. So the two processes share the kernels as they go, whatever each has spent on
other work and however fast this machine's cores run at the time (list scheduling: neither is
idle while a kernel is left), where a split fixed in advance by estimated costs left one of them
idle for seconds.
"""

from __future__ import annotations

import atexit
import os
import shutil
import subprocess
import sys
import tempfile
import time

from ..model.chains import ChainLeg
from ..model.legs import LEG_TYPES
from . import chains, closure, core, held, indices

__all__ = ["CREW", "KERNELS_OF", "LOCAL", "WITH", "STUDY", "STRUCTURE_STUDY", "STRUCTURE_CHAINS", "structure_kinds", "chain_kinds",
           "signatures", "in_cache", "missing", "claim", "compile_ahead", "start_early", "early_queue", "early_kinds",
           "early", "with_kernels",
           "stop_helpers", "started_at", "main"]

#: The kernels of the engine's threads' waits: small, compiled with the feasibility kernel. The
#: compiled crew's hand-off of a feasibility batch (:data:`parasynth.engine.core.SERVE_KERNELS`,
#: :func:`parasynth.engine.core._compiled_batch`; ~3.5 s of compile) is not among them: the
#: first parallel batch of a process whose cache lacks it starts a background helper for it
#: (:func:`parasynth.engine.core.spin_warm`), and the batches go through the interpreter's crew
#: meanwhile.
CREW = ("_spin_done", "_crew_spin")

#: Kernels behind each compiled entry point (the names of :data:`parasynth.engine.EXERCISES`).
KERNELS_OF = {
    "pose": ("_pose_kernel",),
    "twist": ("_pose_kernel",),
    "feasible": ("_pose_kernel", "_feasible_kernel") + CREW,
    "margins": ("_pose_kernel", "_margins_kernel"),
    "singularity_margin": ("_pose_kernel", "_upu_mean_lengths", "_margin_kernel"),
    "transmission": ("_pose_kernel", "_upu_mean_lengths", "_lti_kernel"),
    "condition_number": ("_pose_kernel", "_upu_mean_lengths", "_kappa_kernel"),
    "leg_directions": ("_pose_kernel", "_dir_kernel"),
    "constraint_rank": ("_pose_kernel", "_constraint_rank_kernel"),
    "closure": ("_pose_kernel", "_prep_kernel", "_solve_kernel"),
    "chains": ("_chain_kernel", "_chain_rows_kernel"),
    "chain_closure": ("_closure_kernel",),
}

#: Kernels worth compiling with an entry point's own when a run compiles ahead on its own (no
#: helpers of :func:`start_early`): the singularity margin asks for the design's structural
#: constraint rank (one pose), which runs on NumPy until its kernel is compiled -- ~2 ms of a
#: quick-start design's ~4 ms, against ~2.4 s of compile in the helper that compiles the
#: margin kernel (its callees then cached), which has room beside the interpreter kernels of
#: the calling process. A structure study's early compile has none (docs/performance.md).
WITH = {"singularity_margin": ("_constraint_rank_kernel",)}

#: Kernels compiled in the calling process by :func:`compile_ahead`: they run the expression
#: interpreter, compiled with the first of them (and then cached: a process compiling one later
#: loads it).
LOCAL = ("_pose_kernel", "_feasible_kernel", "_margins_kernel")

# Rough cold-compile CPU seconds (5pus_upu, 2-core development machine), to order the queues
# (longest first) and share the work between new helpers; those of the interpreter kernels
# (LOCAL) without the expression interpreter they share, which the first of them compiled in a
# process compiles (~2.8 s more; numba caches it on the way, so a later one in another process
# loads it): pose 5.1 s and feasibility 11.7 s each alone, feasibility 8.9 s once the
# interpreter is cached.
_COST = {"_spin_done": 0.1, "_crew_spin": 0.1, "_pose_kernel": 2.3, "_feasible_kernel": 8.9, "_margins_kernel": 8.9,
         "_upu_mean_lengths": 0.4,
         "_margin_kernel": 5.0, "_constraint_rank_kernel": 4.5, "_lti_kernel": 6.0, "_kappa_kernel": 5.0,
         "_dir_kernel": 2.0, "_prep_kernel": 2.0, "_solve_kernel": 2.0, "_chain_kernel": 3.0,
         "_chain_rows_kernel": 3.0, "_closure_kernel": 2.5}
#: Helper processes running (see :func:`stop_helpers`).
_RUNNING: list = []
#: Kernels handed to helpers started ahead of the work (:func:`start_early`): name -> the
#: helper process whose queue holds it (the helper compiles it unless the work claims it
#: first, :func:`compile_ahead`).
_EARLY: dict = {}
#: {helper process: (its claim folder, its queue)} of the helpers of :func:`start_early`.
_QUEUES: dict = {}
#: When start_early started its first helper (see :func:`started_at`).
_SINCE: list = []

#: The entry points the shipped structure studies ask for (``engine.needs`` of the warm-up
#: design, the same for structures_1t2r, structures_2t2r and structures_3t2r: the workspace's
#: feasibility, the singularity margin of the home floor and the margin quantile; the
#: structural constraint rank, one pose per design, runs on NumPy unless its kernel is
#: compiled already), compiled from the start of such a run by :func:`start_early` while the
#: structures are enumerated.
STRUCTURE_STUDY = ("feasible", "singularity_margin")
#: What nearly every study asks for, compiled from the start of a run of a study without a
#: ``structure:`` section by :func:`start_early` while the study is checked: the workspace's
#: feasibility, the singularity margin (the home floor of the verification, which every run's
#: recommendation passes, and the margin measures) and the structural constraint rank the margin
#: asks for per design (on NumPy until its kernel is compiled: ~2 ms of a quick-start design).
#: A study asking for other entry points compiles them in its warm-up, as before.
STUDY = ("feasible", "singularity_margin", "constraint_rank")
#: What a structure study with chain limbs (model/chains.py) asks for besides: their compiled
#: inverse kinematics and index rows (the first), and their closure, where a structure's motion is
#: computed from its limbs' closure equations (:func:`chain_kinds`).
STRUCTURE_CHAINS = ("chains", "chain_closure")


def _chain_types() -> set:
    """The names of the chain limb types (model/chains.py) in the limb vocabulary."""
    return {k for k, v in LEG_TYPES.items() if issubclass(v, ChainLeg)}


def structure_kinds(leg_types=None) -> tuple[str, ...]:
    """The entry points a structure study of the limb types ``leg_types`` asks for before its
    structures are enumerated: :data:`STRUCTURE_STUDY`, and the chain limbs' solve
    (``"chains"``) when a chain limb type is among them. None (the default vocabulary, chain
    limbs included) gives :data:`STRUCTURE_STUDY` alone: whether a chain limb is among the
    structures kept is known only once they are enumerated (:func:`chain_kinds` then;
    structures_1t2r keeps none, and its chain kernels would cost ~8 s of compile on the core its
    interpreter kernels need). So is whether their closure is asked for (:func:`chain_kinds`)."""
    if leg_types is not None and any(str(t) in _chain_types() for t in leg_types):
        return STRUCTURE_STUDY + STRUCTURE_CHAINS[:1]
    return STRUCTURE_STUDY


def chain_kinds(structures) -> tuple[str, ...]:
    """What the chain limbs among ``structures`` (enumerated structures,
    :class:`parasynth.structures.Structure`) ask for: their compiled inverse kinematics and index
    rows (``"chains"``) when one has a chain limb, and their closure (``"chain_closure"``) only
    when such a structure's motion is computed from its limbs' closure equations (its
    description's ``task.solve``): a motion template poses the platform without it
    (structures_3t2r's six chain structures; ~2.5 s of compile on the helper that the first
    chain design waits for), else ()."""
    chained = [s for s in structures if any(str(t) in _chain_types() for t in s.leg_counts)]
    if not chained:
        return ()
    if any((s.description.get("task") or {}).get("solve") is not None for s in chained):
        return STRUCTURE_CHAINS
    return STRUCTURE_CHAINS[:1]


def signatures() -> dict:
    """{kernel name: (dispatcher, argument types)} of every kernel of the engine."""
    return {**core.signatures(), **indices.signatures(), **closure.signatures(), **chains.signatures()}


def in_cache(name: str) -> bool:
    """Whether kernel ``name`` is compiled in this process or in numba's cache on disk (read
    from the cache index without loading anything). True when that cannot be told (a numba
    whose cache internals differ): then nothing is compiled ahead."""
    return core.compiled_or_cached(*signatures()[name])


def missing(kinds) -> list[str]:
    """The kernels the entry points ``kinds`` use that are neither compiled nor cached."""
    names = []
    for kind in kinds:
        for n in KERNELS_OF.get(kind, ()):
            if n not in names:
                names.append(n)
    return [n for n in names if not in_cache(n)]


def _compile(name: str) -> None:
    disp, sig = signatures()[name]
    disp.compile(tuple(sig))


def claim(folder: str, name: str) -> bool:
    """Claim kernel ``name`` in the claim folder ``folder`` of a helper's queue: True for the
    first process to ask (it then compiles the kernel), False for any other. A folder that
    cannot be written (removed: the run is over) counts as claimed by nobody else."""
    try:
        os.close(os.open(os.path.join(folder, name), os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
        return True
    except FileExistsError:
        return False
    except OSError:
        return True


def _shares(names: list[str], n: int) -> list[list[str]]:
    """``names`` split over ``n`` processes, longest first onto the least loaded."""
    bins = [[0.0, []] for _ in range(n)]
    for name in sorted(names, key=lambda k: -_COST.get(k, 5.0)):
        b = min(bins, key=lambda b: b[0])
        b[0] += _COST.get(name, 5.0)
        b[1].append(name)
    return [b[1] for b in bins if b[1]]


def compile_ahead(names, processes: int | None = None, poll: float = 0.05) -> dict:
    """Compile kernels ``names`` (not yet cached) into numba's cache: those of :data:`LOCAL`
    here, the others in up to ``processes - 1`` helper processes (default: one fewer than the
    cores, at least one; none on a single core) at the same time, fewer by the helpers of
    :func:`start_early` still running (here, when no core is left). The kernels in the queue
    of such a helper are not compiled twice: those it has not begun are claimed and compiled
    here, in its queue's order, once this process has compiled its own; the others are waited
    for. Returns ``{"local": [...], "helpers": [[...], ...], "failed": [...], "waited":
    [...], "claimed": [...]}`` (failed: kernels of helpers that did not finish; claimed: the
    early helpers' kernels compiled here).
    Helpers still running when this returns or raises (an interrupt) are terminated."""
    names = list(names)
    if processes is None:
        processes = os.cpu_count() or 1
    # kernels in an early helper's queue (start_early): claimed here or waited for below, not
    # compiled twice
    pending = {n: _EARLY[n] for n in names if n in _EARLY and _EARLY[n].poll() is None}
    names = [n for n in names if n not in pending and not (n in _EARLY and in_cache(n))]
    local = [n for n in names if n in LOCAL]
    rest = [n for n in names if n not in LOCAL]
    # cores left for new helpers: one for this process, one for each early helper still running
    free = processes - 1 - len({id(p) for p in pending.values()})
    if free < 1:  # the interpreter kernels last: an early helper may have cached the interpreter by then
        local, rest = rest + local, []
    shares = _shares(rest, min(free, len(rest))) if rest else []
    procs = []
    try:
        env = core.helper_env()
        for share in shares:
            p = subprocess.Popen([sys.executable, "-m", "parasynth.engine.precompile", *share], env=env,
                                 stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            procs.append((share, p))
            _RUNNING.append(p)
        for n in local:
            _compile(n)
        # then what the early helpers have not begun, in their queues' order (longest first)
        claimed = []
        for p, (folder, queue) in list(_QUEUES.items()):
            for n in queue:
                if pending.get(n) is p and claim(folder, n):
                    _compile(n)
                    claimed.append(n)
                    del pending[n]
        failed = []
        for share, p in procs:
            while p.poll() is None:
                time.sleep(poll)
            if p.returncode != 0:
                failed += share
        waited = []
        for n, p in pending.items():
            while p.poll() is None:
                time.sleep(poll)
            waited.append(n)
            if p.returncode != 0:
                failed.append(n)
        return {"local": local, "helpers": shares, "failed": failed, "waited": waited, "claimed": claimed}
    finally:
        _stop([p for _, p in procs])


def start_early(kinds, processes: int | None = None, helper=None) -> list[list[str]]:
    """Start compiling, in a helper process, the kernels of the entry points ``kinds`` (names
    of :data:`KERNELS_OF`) that are neither compiled nor cached, and return at once: for work
    that has something else to do first (a structure study enumerates its structures, several
    seconds of Python on one core, before its first design). The helper is given them all as a
    queue: the longest interpreter kernel first (the feasibility kernel: the helper compiles the
    expression interpreter with it, and numba caches it there for the others), then the others,
    longest first (:data:`_COST`); the first is claimed for it here, and it claims each of the
    others (:func:`claim`) before it compiles it. The work's :func:`compile_ahead` claims the
    rest of the queue as soon as the work gets to it and compiles those kernels in the calling
    process, so that no more processes compile than there are cores (a third process on two
    cores would slow the helper, whose kernel is the longest compile: docs/performance.md) and
    neither waits while a kernel is left. On one core
    the queue is the kernels in the order asked (the work has no core of its own to compile on
    until its warm-up). Returns the queue of each helper started ([] when everything is
    cached). Helpers still running at the end of the process are terminated (what they
    finished is in the cache).

    ``helper``: ``(process, claim folder, started at)`` of a helper started before this
    process imported the engine (``python -m parasynth.engine.precompile --early ...``,
    :mod:`parasynth.cli.early`: ~0.6 s earlier on a first run), which computes this same queue
    itself (:func:`early_queue`) and claims every kernel of it before compiling it: it is taken
    as this queue's helper (unless it has failed already: then one is started as above)."""
    queue = early_queue(kinds, processes)
    adopt = helper is not None and bool(queue) and helper[0].poll() in (None, 0)
    if helper is not None:
        _RUNNING.append(helper[0])  # stopped with the others (it ends by itself when nothing is missing)
        if not adopt:
            _QUEUES[helper[0]] = (helper[1], ())  # its claim folder removed with the others
        _at_exit()
    if not queue:
        return []
    if adopt:
        p, folder = helper[0], helper[1]  # it computed this queue itself, and claims each kernel first
    else:
        folder = tempfile.mkdtemp(prefix="parasynth-claims-")
        claim(folder, queue[0])  # the helper's from the start, however late it starts
        p = subprocess.Popen([sys.executable, "-m", "parasynth.engine.precompile", queue[0], "--claims", folder,
                              *queue[1:]], env=core.helper_env(), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
        _RUNNING.append(p)
    _QUEUES[p] = (folder, tuple(queue))
    for n in queue:
        _EARLY[n] = p
    if not _SINCE:
        _SINCE.append(helper[2] if adopt else time.perf_counter())
    _at_exit()
    return [queue]


def early_queue(kinds, processes: int | None = None) -> list[str]:
    """The queue :func:`start_early` gives its helper for the entry points ``kinds``: the
    kernels neither compiled nor cached (nor handed to a helper already), the longest
    interpreter kernel first, then the others longest first (on one core: in the order asked)."""
    names = [n for n in missing(kinds) if n not in _EARLY]
    if not names:
        return []
    if processes is None:
        processes = os.cpu_count() or 1
    interp = [n for n in names if n in LOCAL]
    rest = [n for n in names if n not in LOCAL]
    if processes < 2:
        return interp + rest
    first = [max(interp, key=lambda k: _COST.get(k, 5.0))] if interp else []
    return first + sorted((n for n in names if n not in first), key=lambda k: -_COST.get(k, 5.0))


def early_kinds(what: str, leg_types=None) -> tuple[str, ...]:
    """The entry points compiled from the start of a run (:func:`start_early`): ``what`` is
    ``"study"`` (:data:`STUDY`) or ``"structure"`` (:func:`structure_kinds` of ``leg_types``)."""
    if what == "study":
        return STUDY
    if what == "structure":
        return structure_kinds(leg_types)
    raise ValueError(f"early compile of {what!r}: allowed are 'study' and 'structure'")


def _at_exit() -> None:
    if not _ATEXIT:
        atexit.register(stop_helpers)
        _ATEXIT.append(True)


_ATEXIT: list = []


def started_at() -> float | None:
    """When :func:`start_early` started its first helper (``time.perf_counter``), or None: the
    compile's elapsed time counts from then."""
    return _SINCE[0] if _SINCE else None


def early() -> dict:
    """{kernel: running} of the kernels :func:`start_early` handed to helpers (running: its
    helper has not finished)."""
    return {n: p.poll() is None for n, p in _EARLY.items()}


def with_kernels(kinds) -> list[str]:
    """The kernels of :data:`WITH` for the entry points ``kinds`` that are neither compiled nor
    cached."""
    names = list(dict.fromkeys(n for k in kinds for n in WITH.get(k, ())))
    return [n for n in names if not in_cache(n)]


def _stop(procs) -> None:
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(5)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
        if p in _RUNNING:
            _RUNNING.remove(p)


def stop_helpers() -> None:
    """Terminate the helper processes still compiling (the caller was interrupted while
    :func:`compile_ahead` waited for them on another thread, the work is over, or the process
    exits), and forget the helpers started ahead (:func:`start_early`): their kernels are in the
    cache, or, a helper terminated or failed, compile where they are needed. So the next work
    of the process (another run of a script, of a test) starts from what the cache holds:
    nothing said ahead for it, nothing queued for it, its compile timed from its own start."""
    _stop(list(_RUNNING))
    for folder, _ in _QUEUES.values():
        shutil.rmtree(folder, ignore_errors=True)
    _QUEUES.clear()
    _EARLY.clear()
    _SINCE.clear()


def main(argv=None) -> int:
    """``python -m parasynth.engine.precompile NAME ... [--hold FILE] [--claims FOLDER NAME ...]``, or
    ``python -m parasynth.engine.precompile --early study|structure [LEG_TYPE ...] --claims FOLDER``: compile
    those kernels into numba's cache, in that order (a helper of :func:`compile_ahead`); those
    after ``--claims`` each only if this process claims it first in ``FOLDER`` (:func:`claim`:
    a helper of :func:`start_early`, whose work may claim some of them). With ``--hold FILE``
    it holds FILE while it compiles (:func:`parasynth.engine.held.hold`), after waiting for
    any other live helper holding it (whose kernels it then loads from the cache: the compiled
    crew's helper of several processes at once). With ``--early`` it compiles the queue of
    :func:`early_queue` for :func:`early_kinds`, each kernel claimed in FOLDER first (the helper
    a run starts before it imports the engine, :func:`start_early`'s ``helper``)."""
    names = list(sys.argv[1:] if argv is None else argv)
    folder, claimed, mark = None, [], None
    if names[:1] == ["--early"]:  # --early study|structure [LEG_TYPE ...] --claims FOLDER
        if "--claims" not in names or names.index("--claims") + 1 >= len(names) or len(names) < 2:
            print("--early needs 'study' or 'structure [LEG_TYPE ...]' and --claims FOLDER", file=sys.stderr)
            return 2
        i = names.index("--claims")
        try:
            kinds = early_kinds(names[1], names[2:i] or None)
        except ValueError as e:
            print(e, file=sys.stderr)
            return 2
        folder = names[i + 1]
        for n in early_queue(kinds):
            if claim(folder, n):
                _compile(n)
        return 0
    if "--hold" in names:  # one such helper at a time on the machine (parasynth.engine.held)
        i = names.index("--hold")
        if i + 1 >= len(names):
            print("--hold needs a file", file=sys.stderr)
            return 2
        mark = names[i + 1]
        names = names[:i] + names[i + 2:]
    if "--claims" in names:
        i = names.index("--claims")
        if i + 1 >= len(names):
            print("--claims needs a folder", file=sys.stderr)
            return 2
        names, folder, claimed = names[:i], names[i + 1], names[i + 2:]
    known = signatures()
    bad = [n for n in names + claimed if n not in known]
    if bad:
        print(f"unknown kernel(s) {', '.join(bad)}; known: {', '.join(known)}", file=sys.stderr)
        return 2
    if mark is not None:
        while not held.hold(mark):  # another helper compiles them: wait, then load them from the cache
            held.wait_let_go(mark)
    try:
        for n in names:
            _compile(n)
        for n in claimed:
            if claim(folder, n):
                _compile(n)
    finally:
        if mark is not None:
            held.let_go(mark)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
