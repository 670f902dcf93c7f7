"""Optuna storages of a study: the embedded journal file, SQLite and PostgreSQL.

Choosing the storage (``--storage URL`` on the command line wins over ``optimizer.storage``
in the study file):

* none given: the embedded journal file ``optuna.journal`` in the run directory -- Optuna's
  ``JournalStorage`` on a file appended under an ``fcntl.flock`` lock, without an ``fsync``
  per operation (``PARASYNTH_FSYNC=1`` adds it). Well under a millisecond per trial, safe for
  several processes on one machine (``--workers N``), not for a network file system.
* ``journal:PATH`` (or ``journal:///abs/path``): the same on a file of your choice.
* ``sqlite:///PATH``: Optuna's RDB storage on SQLite -- one file, but 20-100 ms of commits per
  trial; kept for compatibility.
* ``postgresql://USER:PASSWORD@HOST:PORT/DB`` (any SQLAlchemy URL, e.g.
  ``postgresql+psycopg2://``, ``mysql+pymysql://``): a database server shared by workers on
  several machines (``parasynth worker``). Needs the driver (``pip install psycopg2-binary``).

With any storage, every evaluated design is kept in the storage itself (trial user attribute
``record``: the journal line of the design), with the study file, the reference design and
the final re-evaluation as study user attributes, so that a run directory (results.csv, the
report) can be rebuilt from a server alone: :func:`materialize_run`
(``parasynth report --storage URL --study NAME``).

Which trials count. A trial *counts* (is an evaluated design, in the tables and the budget) if
it is ``COMPLETE``, or ``FAIL`` with a record whose status is ``failed`` (the design could not
be built or measured). A ``FAIL`` trial without such a record was interrupted (Ctrl-C, a killed
worker): it is not counted and its design is proposed again; with a server storage a killed
worker's trial is found by the missing heartbeat, marked ``FAIL`` and retried once.
"""

from __future__ import annotations

import importlib.util
import os
import re
import time
import warnings
from pathlib import Path

from .evaluate import Record
from .journal import rewrite_journal
from .optuna_adapter import copy_study_system_attrs, journal_storage, study_system_attrs_before
from .spec import StudyError, load_study
from .tables import write_tables

__all__ = ["StorageError", "resolve_storage_url", "open_storage", "describe_url", "counts", "records_from_trials",
           "load_parasynth_study", "rebuild_journal_storage", "materialize_run", "is_shared_server",
           "ATTR_STUDY", "ATTR_REFERENCE", "ATTR_FINAL", "ATTR_BUDGET", "ATTR_RECORD", "ATTR_OVER_BUDGET"]

DEFAULT_JOURNAL = "optuna.journal"
ATTR_STUDY = "parasynth:study_yaml"
ATTR_REFERENCE = "parasynth:reference_record"
ATTR_FINAL = "parasynth:final_csv"
ATTR_BUDGET = "parasynth:n_trials"
ATTR_RECORD = "record"
ATTR_OVER_BUDGET = "parasynth:over_budget"  # asked for after the budget was taken: not evaluated

# SQLAlchemy driver module -> the pip command that installs it.
_DRIVER_PIP = {
    "psycopg2": "pip install psycopg2-binary",
    "psycopg": "pip install 'psycopg[binary]'",
    "pg8000": "pip install pg8000",
    "asyncpg": "pip install asyncpg",
    "pymysql": "pip install PyMySQL",
    "MySQLdb": "pip install mysqlclient",
    "mysql": "pip install mysql-connector-python",
}
_CONNECT_TIMEOUT_S = 5


class StorageError(StudyError):
    """A storage URL that cannot be used (unparseable, unreachable, refused, missing driver,
    no such study)."""


def _is_journal(url: str) -> bool:
    return url.startswith("journal:") or "://" not in url


def _journal_path(url: str) -> Path:
    if url.startswith("journal:"):
        rest = url[len("journal:"):]
        if rest.startswith("///"):
            rest = rest[2:]
        elif rest.startswith("//"):
            raise StorageError(f"storage {url!r}: write a journal file as journal:PATH or journal:///ABSOLUTE/PATH")
        url = rest
    if not url:
        raise StorageError("storage: empty journal path; write journal:PATH")
    return Path(url).expanduser()


def describe_url(url: str) -> str:
    """The URL with its password hidden, for messages."""
    try:
        from sqlalchemy.engine import make_url  # lazy: SQLAlchemy is needed only for server storages

        if not _is_journal(url):
            return make_url(url).render_as_string(hide_password=True)
    except Exception:
        pass
    return re.sub(r"(://[^:/@]*):[^@]*@", r"\1:***@", url)


def check_storage_url(url: str) -> str:
    """``url`` when it is a URL (``scheme://...``) or a journal file (``journal:FILE``); a
    :class:`StorageError` otherwise (a bare name is not silently taken as a file name)."""
    if "://" not in url and not url.startswith("journal:"):
        raise StorageError(f"storage {url!r} is neither a URL (postgresql://user:password@host/db, "
                           f"sqlite:///FILE) nor a journal file (journal:FILE); write journal:{url} for a "
                           f"journal file")
    return url


def resolve_storage_url(study, out_dir, override: str | None = None) -> str:
    """``override`` (``--storage``), else ``optimizer.storage``, else the run directory's
    journal file."""
    url = override or study.optimizer.storage
    if url is not None:
        url = str(url).strip()
        if not url:
            raise StorageError("storage: empty URL; give a URL such as postgresql://user:password@host/db, "
                               "sqlite:///optuna.db or journal:optuna.journal")
        check_storage_url(url)
        return url
    return f"journal:{(Path(out_dir) / DEFAULT_JOURNAL).resolve()}"


def is_shared_server(url: str) -> bool:
    """True for a database server (workers on other machines can join)."""
    return not _is_journal(url) and not url.startswith("sqlite")


# -- the embedded journal file --------------------------------------------------------------------------
def _open_journal(url: str):
    path = _journal_path(url)
    if path.exists() and path.is_dir():
        raise StorageError(f"storage {url!r}: {str(path)!r} is a directory; give a file path")
    if not path.parent.exists():
        raise StorageError(f"storage {url!r}: folder {str(path.parent)!r} does not exist")
    try:
        return journal_storage(path)
    except PermissionError:
        raise StorageError(f"storage {url!r}: no permission to write {str(path)!r}") from None
    except ValueError as e:
        raise StorageError(f"storage {url!r}: the journal file {str(path)!r} is damaged ({e})") from None


# -- database servers ----------------------------------------------------------------------------------
def _check_rdb(url: str):
    """Parse the URL, import its driver and connect once: one clear message for each way
    this fails, before any work starts."""
    from sqlalchemy import create_engine, text  # lazy: SQLAlchemy is needed only for server storages
    from sqlalchemy.engine import make_url  # lazy: as above
    from sqlalchemy.exc import ArgumentError, NoSuchModuleError, OperationalError, SQLAlchemyError  # lazy: as above

    shown = describe_url(url)
    try:
        u = make_url(url)
        u.port  # noqa: B018 (a port that is not a number fails here)
    except (ArgumentError, ValueError):
        raise StorageError(f"storage {shown!r}: not a storage URL; expected e.g. "
                           f"postgresql://USER:PASSWORD@HOST:5432/DATABASE, sqlite:///optuna.db or journal:FILE") from None
    if u.drivername in ("postgresql", "postgres"):
        # No driver named: psycopg (3) or psycopg2, whichever is installed.
        for mod, name in (("psycopg", "postgresql+psycopg"), ("psycopg2", "postgresql+psycopg2")):
            if importlib.util.find_spec(mod) is not None:
                u = u.set(drivername=name)
                break
        else:
            raise StorageError(f"storage {shown!r}: no PostgreSQL driver is installed; install one with: "
                               f"pip install psycopg2-binary")
    try:
        dialect = u.get_dialect()
    except NoSuchModuleError:
        raise StorageError(f"storage {shown!r}: unknown database kind {u.drivername!r}; use postgresql, mysql, "
                           f"sqlite or journal") from None
    try:
        dialect.import_dbapi()
    except ImportError as e:
        mod = (getattr(e, "name", None) or u.get_driver_name() or u.drivername).split(".")[0]
        pip = _DRIVER_PIP.get(mod, f"pip install {mod}")
        raise StorageError(f"storage {shown!r}: the database driver {mod!r} is not installed; install it with: {pip}") from None
    kw = {}
    if u.get_backend_name() == "postgresql" and u.get_driver_name() in ("psycopg2", "psycopg"):
        kw["connect_args"] = {"connect_timeout": _CONNECT_TIMEOUT_S}
    elif u.get_backend_name() == "mysql":
        kw["connect_args"] = {"connect_timeout": _CONNECT_TIMEOUT_S}
    try:
        eng = create_engine(u, **kw)
        with eng.connect() as c:
            c.execute(text("SELECT 1"))
        eng.dispose()
    except OperationalError as e:
        msg = str(e.orig if getattr(e, "orig", None) is not None else e).strip().splitlines()[0]
        low = msg.lower()
        if "password" in low or "authentication" in low or "access denied" in low or "role" in low:
            why = "the server refused the credentials"
        elif "does not exist" in low or "unknown database" in low:
            why = "no such database on the server"
        elif u.get_backend_name() == "sqlite":
            why = "cannot open the SQLite file"
        else:
            why = "cannot reach the server"
        raise StorageError(f"storage {shown!r}: {why} ({msg})") from None
    except SQLAlchemyError as e:
        raise StorageError(f"storage {shown!r}: {type(e).__name__}: {str(e).splitlines()[0]}") from None
    return u, kw


def open_storage(url: str, heartbeat: bool = True):
    """An Optuna storage for ``url``, checked (driver, connection) first. Database servers get
    a heartbeat: a trial whose worker stopped beating for ``grace_period`` seconds is marked
    failed and retried once (``PARASYNTH_HEARTBEAT`` sets the interval, default 5 s)."""
    check_storage_url(url)
    if _is_journal(url):
        return _open_journal(url)
    u, kw = _check_rdb(url)
    url = u.render_as_string(hide_password=False)
    import optuna  # lazy: optuna takes about a second to import
    from optuna.storages import RDBStorage  # lazy: as above

    try:
        from optuna.storages import RetryHeartbeatStaleTrialCallback as Retry  # lazy: optuna
    except ImportError:  # Optuna < 4.9
        from optuna.storages import RetryFailedTrialCallback as Retry  # lazy: optuna

    engine_kwargs = {"pool_pre_ping": True, **kw}
    for attempt in range(SCHEMA_ATTEMPTS):
        try:
            with warnings.catch_warnings():
                # heartbeats are "experimental" in Optuna: nothing for a user of the command line
                # to act on.
                warnings.simplefilter("ignore")
                options = {}
                if heartbeat and u.get_backend_name() != "sqlite":
                    interval = max(1, int(float(os.environ.get("PARASYNTH_HEARTBEAT", "5"))))
                    options = dict(heartbeat_interval=interval, grace_period=3 * interval,
                                   heartbeat_stale_trial_callback=Retry(max_retry=1))
                return RDBStorage(url, engine_kwargs=engine_kwargs, **options)
        except optuna.exceptions.StorageInternalError as e:
            raise StorageError(f"storage {describe_url(url)!r}: {e}") from None
        except Exception as e:  # schema creation refused, incompatible schema version, ...
            if attempt + 1 < SCHEMA_ATTEMPTS and _schema_race(e):
                time.sleep(0.2 * (attempt + 1))  # another process is creating the tables: they exist next time
                continue
            first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise StorageError(f"storage {describe_url(url)!r}: cannot use it as an Optuna storage ({first})") from None
    raise AssertionError("unreachable")  # pragma: no cover


#: Attempts at opening a database storage whose first schema creation races with another
#: process's (:func:`_schema_race`).
SCHEMA_ATTEMPTS = 5


def _schema_race(e: BaseException) -> bool:
    """Whether ``e`` is what a database says when two processes create Optuna's tables in a new
    database at once (workers started together on a fresh PostgreSQL database): the loser's
    ``CREATE TABLE`` collides with the winner's (a unique violation on the catalogue, or "already
    exists"). The tables are there then, so opening the storage again succeeds."""
    from sqlalchemy.exc import IntegrityError, ProgrammingError  # lazy: SQLAlchemy loads with Optuna

    while e is not None:
        if isinstance(e, (IntegrityError, ProgrammingError)):
            text_ = str(e).lower()
            return "duplicate key" in text_ or "already exists" in text_
        e = e.__cause__ or e.__context__
    return False


def study_names(storage) -> list[str]:
    return [s.study_name for s in storage.get_all_studies()]


def load_parasynth_study(storage, url: str, name: str):
    """The Optuna study ``name`` in ``storage``, or a clear error listing the studies there."""
    import optuna  # lazy: optuna takes about a second to import

    try:
        return optuna.load_study(study_name=name, storage=storage)
    except KeyError:
        names = study_names(storage)
        there = ", ".join(repr(n) for n in names) if names else "none"
        raise StorageError(f"storage {describe_url(url)!r} holds no study named {name!r} (studies there: {there}); "
                           f"start it with: parasynth run STUDY.yaml --storage URL") from None


def name_objectives(ostudy, study) -> None:
    """Give the Optuna study ``ostudy`` the objective labels of ``study`` as its metric names
    (``study.set_metric_names``), in the order of its directions, so that optuna-dashboard and
    ``trials_dataframe`` show ``volume`` rather than ``values_0``. Written once: names already
    stored are not written again (a worker joining, a resumed run)."""
    import optuna  # lazy: optuna takes about a second to import

    names = [o.label for o in study.objectives]
    with warnings.catch_warnings():  # the metric names are experimental in Optuna (3.2 onwards)
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        if ostudy.metric_names != names:
            ostudy.set_metric_names(names)


# -- records ---------------------------------------------------------------------------------------------
def trial_record(t) -> Record | None:
    d = t.user_attrs.get(ATTR_RECORD)
    if not isinstance(d, dict):
        return None
    rec = Record.from_dict(d)
    rec.trial = t.number
    rec.source = "run"
    return rec


def counts(t) -> bool:
    """Does trial ``t`` count as an evaluated design (see the module docstring)?"""
    from optuna.trial import TrialState  # lazy: optuna takes about a second to import

    if t.state == TrialState.COMPLETE:
        return True
    if t.state == TrialState.FAIL:
        d = t.user_attrs.get(ATTR_RECORD)
        return isinstance(d, dict) and d.get("status") == "failed"
    return False


def records_from_trials(trials) -> list[Record]:
    out = []
    for t in sorted(trials, key=lambda t: t.number):
        if counts(t):
            rec = trial_record(t)
            if rec is not None:
                out.append(rec)
    return out


def reference_record(ostudy) -> Record | None:
    d = ostudy.user_attrs.get(ATTR_REFERENCE)
    return Record.from_dict(d) if isinstance(d, dict) else None


def rebuild_journal_storage(url: str, name: str) -> int:
    """Before resuming in a run directory (no other process runs: the run lock is held),
    rewrite the embedded journal storage with the study's attributes and its counted trials
    only, in their order: the interrupted trials disappear, so trial numbers -- and with the
    per-trial seeding of the sampler, its proposals -- continue exactly as in an uninterrupted
    run. When the dropped trials are the last ones (a one-process run), the study's system
    attributes (where samplers keep state: NSGA-II's parents of each generation, QMC's point
    counter) are those from before the first of them was asked, so it is asked again exactly
    as then. Returns the number of trials dropped."""
    import optuna  # lazy: optuna takes about a second to import

    path = _journal_path(url)
    if not path.exists():
        return 0
    old = _open_journal(url)
    try:
        src = optuna.load_study(study_name=name, storage=old)
    except KeyError:
        return 0
    trials = src.get_trials(deepcopy=False)
    keep = [t for t in trials if counts(t)]
    if len(keep) == len(trials) and [t.number for t in keep] == list(range(len(keep))):
        return 0
    tmp = path.with_name(path.name + ".rebuild")
    for p in (tmp, Path(str(tmp) + ".flock")):
        if p.exists():
            p.unlink()
    new_storage = journal_storage(tmp)
    dst = optuna.create_study(study_name=name, storage=new_storage, directions=src.directions)
    dropped = [t.number for t in trials if not counts(t)]
    attrs = None
    if dropped and min(dropped) >= len(keep):
        # The interrupted trials are the last ones: give the study the sampler state from
        # before the first of them was asked, so it is asked again exactly as the
        # uninterrupted run asks it (same number, same seed, same sampler state).
        attrs = study_system_attrs_before(path, src, min(dropped), keep)
    copy_study_system_attrs(old, src, new_storage, dst, attrs)
    for k, v in src.user_attrs.items():
        dst.set_user_attr(k, v)
    dst.add_trials(keep)
    del new_storage, dst
    os.replace(tmp, path)
    try:
        os.unlink(str(tmp) + ".flock")
    except OSError:
        pass
    return len(trials) - len(keep)


def materialize_run(url: str, name: str, run_dir) -> Path:
    """Write a run directory (``study.yaml``, ``journal.jsonl``, ``results.csv``,
    ``final.csv``) from a storage alone, for ``parasynth report --storage URL --study NAME``."""
    storage = open_storage(url, heartbeat=False)
    ostudy = load_parasynth_study(storage, url, name)
    text = ostudy.user_attrs.get(ATTR_STUDY)
    if not text:
        raise StorageError(f"study {name!r} in {describe_url(url)!r} was not started by parasynth run "
                           f"(no study file stored with it)")
    study = load_study(text, is_text=True)
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "study.yaml").write_text(text)
    recs = records_from_trials(ostudy.get_trials(deepcopy=False))
    ref = reference_record(ostudy)
    rewrite_journal(run_dir / "journal.jsonl", ([ref] if ref is not None else []) + recs)
    final = ostudy.user_attrs.get(ATTR_FINAL)
    if final:
        (run_dir / "final.csv").write_text(final)
    write_tables(study, run_dir, ([ref] if ref is not None else []) + recs)
    return run_dir
