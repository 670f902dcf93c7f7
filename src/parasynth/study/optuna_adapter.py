"""Every use of Optuna's private interfaces, in one place.

Optuna's public API does not cover what parasynth needs for safe parallel runs; what it
reaches into is kept here, so that an Optuna release that changes it breaks one module:

* :func:`flock_journal_backend` -- a subclass of ``JournalFileBackend`` that appends under
  ``fcntl.flock`` and reads on a kept file handle; its ``read_logs`` follows Optuna's own
  (it uses the backend's ``_file_path`` and ``_log_number_offset``);
* :func:`heartbeat` -- ``optuna.storages._heartbeat`` (the heartbeat thread of ask-and-tell
  loops on server storages);
* :func:`fail_trial`, :func:`trial_storage` -- a study's ``_storage`` and a trial's
  ``_trial_id`` (to fail a trial left running by a dead process);
* :func:`copy_study_system_attrs` -- ``_study_id`` (to rebuild a journal storage with the
  study's system attributes);
* :class:`StructureView` -- a study seen through one structure of a study over structures:
  its ``get_trials`` and the private ``_get_trials`` the samplers call filtered by a trial
  system attribute (as Optuna's ``_BracketStudy`` of the Hyperband pruner);
  :func:`set_trial_system_attr` -- the study's ``_storage`` and a trial's ``_trial_id``;
* :func:`study_system_attrs_before` -- the operation log of ``JournalStorage`` (its
  ``op_code`` values, ``JournalOperation``): the study's system attributes as they were
  before a given trial was created, for a resume that asks that trial again as the
  uninterrupted run asked it.

Optuna is imported inside the functions: a sweep or an NLopt run never imports it.
"""

from __future__ import annotations

import contextlib
import copy
import fcntl
import json
import os
import warnings

__all__ = ["flock_journal_backend", "journal_storage", "heartbeat", "trial_storage", "fail_trial",
           "copy_study_system_attrs", "study_system_attrs_before", "fail_stale", "StructureView", "StructureIndex", "study_identity",
           "set_trial_system_attr"]


def flock_journal_backend(path):
    """Optuna's journal file backend on ``path``, appended under ``fcntl.flock`` (see the class)."""
    from optuna.storages.journal import JournalFileBackend  # lazy: optuna takes about a second to import

    class FlockJournalBackend(JournalFileBackend):
        """Optuna's journal file, appended under ``fcntl.flock`` (released by the operating
        system when a process dies, so a killed worker never leaves it locked), ``fsync`` only
        with ``PARASYNTH_FSYNC=1``. A line cut by a crash at the end of the file is removed
        on open, under the lock, so the next operation does not append onto it."""

        def __init__(self, file_path: str):
            self._fcntl = fcntl
            self._lock_path = file_path + ".flock"
            self._fsync = os.environ.get("PARASYNTH_FSYNC", "").strip().lower() in ("1", "true", "yes", "on")
            self._lock_fd = os.open(self._lock_path, os.O_CREAT | os.O_RDWR, 0o644)
            super().__init__(file_path, lock_obj=None)
            fcntl.flock(self._lock_fd, fcntl.LOCK_EX)
            try:
                with open(file_path, "rb+") as f:
                    data = f.read()
                    if data and not data.endswith(b"\n"):
                        f.truncate(data.rfind(b"\n") + 1)
            finally:
                fcntl.flock(self._lock_fd, fcntl.LOCK_UN)
            self._fd = os.open(file_path, os.O_WRONLY | os.O_APPEND)

        def read_logs(self, log_number_from: int):
            # As Optuna's, on a file handle kept open (no open/close per storage operation).
            f = getattr(self, "_rf", None)
            if f is None:
                f = self._rf = open(self._file_path, "rb")
            remaining = os.fstat(f.fileno()).st_size
            start = 0
            if log_number_from in self._log_number_offset:
                f.seek(self._log_number_offset[log_number_from])
                start = log_number_from
                remaining -= self._log_number_offset[log_number_from]
            else:
                f.seek(0)
            last_error = None
            for number, line in enumerate(f, start=start):
                remaining -= len(line)
                if remaining < 0:
                    break
                if last_error is not None:
                    raise last_error
                if not line.endswith(b"\n"):
                    last_error = ValueError("Invalid log format.")
                    continue
                if number + 1 not in self._log_number_offset:
                    self._log_number_offset[number + 1] = self._log_number_offset[number] + len(line)
                if number < log_number_from:
                    continue
                try:
                    yield json.loads(line)
                except json.JSONDecodeError as err:
                    last_error = err
                    del self._log_number_offset[number + 1]

        def append_logs(self, logs):
            data = ("\n".join(json.dumps(log, separators=(",", ":")) for log in logs) + "\n").encode("utf-8")
            self._fcntl.flock(self._lock_fd, self._fcntl.LOCK_EX)
            try:
                os.write(self._fd, data)
                if self._fsync:
                    os.fsync(self._fd)
            finally:
                self._fcntl.flock(self._lock_fd, self._fcntl.LOCK_UN)

        def close(self):
            """Close the files this backend holds (it is not used afterwards)."""
            f = getattr(self, "_rf", None)
            if f is not None:
                f.close()
                self._rf = None
            for fd in (self._fd, self._lock_fd):
                with contextlib.suppress(OSError):
                    os.close(fd)

        def __getstate__(self):
            raise TypeError("the journal backend holds open files; open it again in each process")

    return FlockJournalBackend(str(path))


def journal_storage(path):
    """Optuna's ``JournalStorage`` on the file ``path`` (:func:`flock_journal_backend`)."""
    from optuna.storages import JournalStorage  # lazy: optuna takes about a second to import

    return JournalStorage(flock_journal_backend(path))


def trial_storage(ostudy):
    """The storage object of an Optuna study (``Study._storage``)."""
    return ostudy._storage


def fail_trial(ostudy, trial):
    """Mark ``trial`` (a trial or frozen trial of ``ostudy``) failed in the storage."""
    from optuna.trial import TrialState  # lazy: optuna takes about a second to import

    ostudy._storage.set_trial_state_values(trial._trial_id, state=TrialState.FAIL)


def copy_study_system_attrs(src_storage, src_study, dst_storage, dst_study, attrs: dict | None = None):
    """Copy the system attributes of ``src_study`` (in ``src_storage``) to ``dst_study``, or
    give it ``attrs`` when given."""
    if attrs is None:
        attrs = src_storage.get_study_system_attrs(src_study._study_id)
    for k, v in attrs.items():
        dst_storage.set_study_system_attr(dst_study._study_id, k, v)


def study_system_attrs_before(path, study, first_dropped: int, kept) -> dict | None:
    """The system attributes of ``study`` (loaded from the journal file ``path``) as they were
    just before its trial number ``first_dropped`` was created, by replaying the journal's
    operations up to there; ``None`` when a trial of ``kept`` (trials that stay) was written
    after that point (then the attributes written since may be theirs, and are kept).

    Samplers keep state in these attributes (NSGA-II/III cache each generation's parents,
    ordered as their selection returned them, when the first trial of the generation is asked;
    QMC counts its points there). A trial dropped on resume must be asked again from the state
    it was first asked from, or its proposal differs from the uninterrupted run's."""
    from optuna.storages import JournalStorage  # lazy: optuna takes about a second to import

    try:
        from optuna.storages.journal import BaseJournalBackend  # lazy: as above
        from optuna.storages.journal._storage import JournalOperation  # lazy: as above
    except ImportError:  # pragma: no cover (an Optuna < 4 journal layout: the attributes are kept as they are)
        return None

    class _Logs(BaseJournalBackend):
        def __init__(self, logs):
            self._logs = logs

        def read_logs(self, log_number_from):
            return self._logs[log_number_from:]

        def append_logs(self, logs):  # pragma: no cover (read only)
            raise TypeError("read-only journal replay")

    sid = study._study_id
    kept_ids = {t._trial_id for t in kept}
    backend = flock_journal_backend(path)
    try:
        logs = list(backend.read_logs(0))
    finally:
        backend.close()
    created = 0
    cut = None
    for i, log in enumerate(logs):
        if log.get("op_code") == JournalOperation.CREATE_TRIAL and log.get("study_id") == sid:
            if created == first_dropped:
                cut = i
                break
            created += 1
    if cut is None:
        return None
    if any(log.get("trial_id") in kept_ids for log in logs[cut:]):
        return None
    return dict(JournalStorage(_Logs(logs[:cut])).get_study_system_attrs(sid))


def heartbeat():
    """``(get_thread(trial_id, storage), is_enabled(storage))`` of Optuna's heartbeat; no-ops
    for an Optuna without heartbeats."""
    try:
        from optuna.storages._heartbeat import get_heartbeat_thread, is_heartbeat_enabled  # lazy: optuna
    except ImportError:  # pragma: no cover (an Optuna without heartbeats)
        return (lambda trial_id, storage: contextlib.nullcontext()), (lambda storage: False)
    return get_heartbeat_thread, is_heartbeat_enabled


def heartbeat_thread(ostudy, trial):
    """The heartbeat context of ``trial`` while it is evaluated (a no-op without heartbeat)."""
    get_thread, _ = heartbeat()
    return get_thread(trial._trial_id, ostudy._storage)


def heartbeat_enabled(ostudy) -> bool:
    return bool(heartbeat()[1](ostudy._storage))


def fail_stale(ostudy):
    """Fail the trials whose heartbeat stopped (``optuna.storages.fail_stale_trials``, an
    experimental function: its warning is silenced), ignoring storage errors."""
    import optuna  # lazy: optuna takes about a second to import

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with contextlib.suppress(Exception):
            optuna.storages.fail_stale_trials(ostudy)


def set_trial_system_attr(study, trial, key: str, value) -> None:
    """Set a system attribute of the (frozen) ``trial`` of ``study`` in the storage."""
    study._storage.set_trial_system_attr(trial._trial_id, key, value)


def study_identity(study) -> tuple:
    """What tells one Optuna study from another in this process: its storage object and its id
    there."""
    return id(study._storage), study._study_id


class StructureIndex:
    """The trial numbers of each structure of one Optuna study (the system attribute ``attr`` of
    its trials), kept across the proposals of a run: each call reads only the trials it has not
    classified yet, so that a structure's view (:class:`StructureView`) picks its trials instead
    of testing every stored trial each time its sampler asks (O(n^2) over a run: ~0.8 s of a
    1,050-trial structures_3t2r). A trial's structure is written once, when it is asked for; a
    trial still running without one (just created by another process) stops the classification
    there until it has one or has finished (then it belongs to no structure, as for the view)."""

    def __init__(self, attr: str):
        self._attr = attr
        self._of: dict = {}  # structure -> its trial numbers, ascending
        self._done = 0  # trials 0 .. _done - 1 classified

    def numbers(self, trials, structure) -> list[int] | None:
        """The numbers of the trials of ``structure`` among ``trials`` (every trial of the study,
        in number order, as Optuna's storages give them), ascending; None where ``trials`` is not
        such a list (the caller then tests each trial)."""
        n = len(trials)
        i = self._done
        while i < n:
            t = trials[i]
            if t.number != i:
                return None
            s = t.system_attrs.get(self._attr)
            if s is None and not t.state.is_finished():
                break
            if s is not None:
                self._of.setdefault(s, []).append(i)
            i += 1
        self._done = i
        mine = [j for j in self._of.get(structure, ()) if j < n]
        if i < n:  # after an unclassified running trial: tested one by one, not kept
            mine += [j for j in range(i, n) if trials[j].system_attrs.get(self._attr) == structure]
        return mine


class StructureView:
    """An Optuna study seen through one structure: ``get_trials`` and ``_get_trials`` return
    only the trials whose system attribute ``attr`` is ``structure``, in the study's order
    (picked by ``index``, a :class:`StructureIndex` of the study kept by the caller, where
    given); everything else is the study's. Each structure's sampler proposes from its own
    history, as Optuna's Hyperband pruner gives each bracket's sampler its own trials."""

    def __init__(self, study, attr: str, structure: str, index: StructureIndex | None = None):
        self._study = study
        self._attr = attr
        self._structure = structure
        self._index = index

    def __getattr__(self, name):
        return getattr(self._study, name)

    def _mine(self, trials):
        return [t for t in trials if t.system_attrs.get(self._attr) == self._structure]

    def get_trials(self, deepcopy: bool = True, states=None):
        return self._get_trials(deepcopy=deepcopy, states=states)

    def _get_trials(self, deepcopy: bool = True, states=None, use_cache: bool = False):
        if self._index is not None:
            every = self._study._get_trials(deepcopy=False, states=None, use_cache=use_cache)
            nums = self._index.numbers(every, self._structure)
            if nums is not None:
                picked = [every[j] for j in nums]
                if states is not None:
                    picked = [t for t in picked if t.state in states]
                return copy.deepcopy(picked) if deepcopy else picked
        return self._mine(self._study._get_trials(deepcopy=deepcopy, states=states, use_cache=use_cache))

    @property
    def trials(self):
        return self.get_trials()
