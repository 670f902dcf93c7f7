"""The run journal and the run-directory lock.

Journal
-------
``journal.jsonl`` in a run directory holds one JSON line per evaluated design (a
:class:`~parasynth.study.evaluate.Record`), appended and flushed as soon as the design is
evaluated. A flushed line survives the process being killed (it is in the operating system's
buffers); it survives a power loss only once the system has written it out, which
``PARASYNTH_FSYNC=1`` forces after every line (about 0.3 ms per design on a local SSD).

A line cut by a power loss or a full disk (a *torn* last line: no final newline, or text that
is not JSON) is detected when the journal is read. On resume it is truncated away, with a
message, so the next record starts on a line of its own; the design it held is evaluated
again. A damaged line that is *not* the last one is not something a crash produces: reading
stops with an error naming the file and line.

Lock
----
One process writes a run directory at a time: :class:`RunLock` holds an exclusive
``fcntl.flock`` on ``run.lock`` for the life of the run and writes the owner's pid, host and
start time into it. The operating system drops the lock when the owner exits, however it
exits (SIGKILL and crashes included), so a crashed run never leaves the directory stuck; the
file itself stays behind, harmless.
"""

from __future__ import annotations

import fcntl
import json
import os
import socket
import sys
import time
from pathlib import Path

import numpy as np

from .evaluate import Record
from .spec import StudyError

__all__ = ["Journal", "read_journal", "rewrite_journal", "JournalError", "RunLock", "RunLockedError", "json_default",
           "jsonable"]

LOCK_NAME = "run.lock"


class JournalError(StudyError):
    """A journal line that cannot be read and is not a torn last line."""


class RunLockedError(StudyError):
    """Another live process holds the run directory."""


def json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


def jsonable(d: dict) -> dict:
    """``d`` with NumPy scalars and arrays and tuples turned into JSON types (as stored in an
    Optuna storage's attributes)."""
    return json.loads(json.dumps(d, default=json_default))


def record_json(rec: Record) -> str:
    return json.dumps(rec.to_dict(), default=json_default, allow_nan=True)


def _fsync_wanted() -> bool:
    return os.environ.get("PARASYNTH_FSYNC", "").strip().lower() in ("1", "true", "yes", "on")


class Journal:
    """Append-only JSON-lines file of records (one writer: the holder of the run lock)."""

    def __init__(self, path: Path, fsync: bool | None = None):
        self.path = Path(path)
        self.fsync = _fsync_wanted() if fsync is None else fsync
        self.f = open(self.path, "a", encoding="utf-8")

    def append(self, rec: Record):
        self.f.write(record_json(rec) + "\n")
        self.f.flush()
        if self.fsync:
            os.fsync(self.f.fileno())

    def close(self):
        if not self.f.closed:
            self.f.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _not_a_record(obj) -> str:
    """Why a parsed journal line is not a design record ('' when it is one)."""
    if not isinstance(obj, dict):
        return f"a JSON {type(obj).__name__.replace('dict', 'object').replace('str', 'string')}, not an object"
    if not isinstance(obj.get("values"), dict):
        return "no 'values' mapping of design variables"
    for key in ("objectives", "constraint_values", "margins"):
        if key in obj and not isinstance(obj[key], dict):
            return f"'{key}' is not a mapping"
    if "trial" in obj and (not isinstance(obj["trial"], int) or isinstance(obj["trial"], bool)):
        return "'trial' is not an integer"
    if "source" in obj and obj["source"] not in ("run", "reference"):
        return f"'source' is {obj['source']!r}, not 'run' or 'reference'"
    return ""


def _scan(path: Path):
    """(records, good_bytes, torn) of one journal file: ``good_bytes`` is the length of the
    intact part; ``torn`` the text of a damaged last line, if any."""
    data = path.read_bytes()
    records = []
    pos = 0
    n = len(data)
    lineno = 0
    while pos < n:
        end = data.find(b"\n", pos)
        last = end < 0 or data[end + 1:].strip() == b""
        line = data[pos:] if end < 0 else data[pos:end]
        lineno += 1
        if line.strip():
            try:
                if end < 0:
                    raise ValueError("no final newline")
                obj = json.loads(line.decode("utf-8"))
            except (ValueError, UnicodeDecodeError) as e:
                obj, err = None, e
            else:
                err = None
            if err is None:
                # A whole line of valid JSON is no cut left by a crash: it must be a record.
                problem = _not_a_record(obj)
                if problem:
                    raise JournalError(f"{path}: line {lineno} is valid JSON but not a design record ({problem}); "
                                       f"remove or repair the line, or start a new run (--out)")
                try:
                    records.append(Record.from_dict(obj))
                except (ValueError, KeyError, TypeError, AttributeError) as e:
                    raise JournalError(f"{path}: line {lineno} is not a design record ({type(e).__name__}: {e}); "
                                       f"remove or repair the line, or start a new run (--out)") from None
            else:
                e = err
                if last:
                    return records, pos, line
                raise JournalError(
                    f"{path}: line {lineno} is damaged ({type(e).__name__}: {e}) and is not the last line; "
                    f"this is not a cut caused by a crash -- remove or repair the line, or start a new run (--out)"
                ) from None
        if end < 0:
            break
        pos = end + 1
    return records, n, None


def read_journal(out_dir: Path, repair: bool = False, warn=None) -> list[Record]:
    """Records of every ``journal*.jsonl`` in ``out_dir``, one per (source, trial): a later
    line for the same key replaces an earlier one.

    A torn last line is skipped; with ``repair=True`` (resume) the file is truncated to its
    intact part and ``warn`` (default: print to stderr) says so."""
    warn = warn or (lambda msg: print(msg, file=sys.stderr))
    out: dict[tuple, Record] = {}
    order: list[tuple] = []
    for p in sorted(Path(out_dir).glob("journal*.jsonl")):
        recs, good, torn = _scan(p)
        if torn is not None:
            if repair:
                with open(p, "r+b") as f:
                    f.truncate(good)
                warn(f"{p}: the last line was cut ({len(torn)} bytes, e.g. by a power loss or a full disk); "
                     f"it is removed and that design is evaluated again")
        for r in recs:
            k = (r.source, r.trial)
            if k not in out:
                order.append(k)
            out[k] = r
    return [out[k] for k in order]


def rewrite_journal(path: Path, records: list[Record]):
    """Replace a journal atomically with ``records`` (used when the records are rebuilt from
    an Optuna storage)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        for r in records:
            f.write(record_json(r) + "\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


class RunLock:
    """Exclusive lock of a run directory (``run.lock``), released by the operating system
    when the holder exits in any way."""

    def __init__(self, out_dir: Path):
        self.path = Path(out_dir) / LOCK_NAME
        self.f = None

    def acquire(self) -> "RunLock":
        f = open(self.path, "a+", encoding="utf-8")
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.seek(0)
            owner = f.read().strip() or "unknown process"
            f.close()
            raise RunLockedError(
                f"run directory {str(self.path.parent)!r} is in use by another run ({owner}); wait for it to "
                f"finish or stop it (Ctrl-C), or choose another directory with --out"
            ) from None
        f.seek(0)
        f.truncate()
        f.write(f"pid {os.getpid()} on host {socket.gethostname()} since "
                f"{time.strftime('%Y-%m-%d %H:%M:%S', time.localtime())}\n")
        f.flush()
        self.f = f
        return self

    def release(self):
        if self.f is not None:
            try:
                fcntl.flock(self.f.fileno(), fcntl.LOCK_UN)
            finally:
                self.f.close()
                self.f = None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()
