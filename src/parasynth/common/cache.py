"""Results kept on disk between processes, keyed by what they are computed from and by the code
that computes them.

Some answers take seconds and depend only on their arguments and on parasynth itself: the
structures of a motion type (:func:`parasynth.structures.structures`, 2-20 s, asked again by
every run and ``validate`` of a structure study and by every ``parasynth structures`` call).
:func:`load` and :func:`save` keep such an answer as a pickle under the cache folder
(:func:`parasynth.common.qmc.cache_dir`: ``$PARASYNTH_CACHE_DIR``, else
``$XDG_CACHE_HOME/parasynth``, else ``~/.cache/parasynth``; ``PARASYNTH_CACHE_DIR=off``
disables it), in a folder per kind, under a name that is the SHA-256 of the key and of
:func:`code_fingerprint`: the content of every source and data file of the installed parasynth
package and the versions of Python, NumPy and SciPy. A changed file of parasynth, or another
NumPy, gives other names, so an answer is never taken from other code; the old files are left
(tens of kilobytes each; delete the folder to reclaim them).

A file that cannot be read, does not unpickle or holds another kind of object counts as absent
(the answer is computed and the file replaced); a folder that cannot be written is skipped
silently (the answer is computed every time, as without a cache). Files are written whole
(a temporary file renamed), so a process that stops while writing leaves no partial file that
another would read.
"""

from __future__ import annotations

import functools
import hashlib
import os
import pickle
import platform
import tempfile
from importlib import metadata
from pathlib import Path

import numpy as np

from .qmc import cache_dir

__all__ = ["code_fingerprint", "load", "save", "path_for"]

#: File types of the package whose content is part of :func:`code_fingerprint`.
_SOURCES = (".py", ".yaml", ".yml", ".json")


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """SHA-256 (hex) of the installed parasynth package's source and data files (relative path
    and content, in path order) and of the Python, NumPy and SciPy versions (~10 ms, computed
    once per process)."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for p in sorted(root.rglob("*")):
        if p.suffix in _SOURCES and "__pycache__" not in p.parts and p.is_file():
            data = p.read_bytes()
            h.update(p.relative_to(root).as_posix().encode())
            h.update(len(data).to_bytes(8, "little"))
            h.update(data)
    try:
        scipy_version = metadata.version("scipy")
    except metadata.PackageNotFoundError:  # pragma: no cover - scipy is a dependency
        scipy_version = "none"
    h.update(f"python {platform.python_version()} numpy {np.__version__} scipy {scipy_version}".encode())
    return h.hexdigest()


def path_for(kind: str, key) -> Path | None:
    """The file of ``key`` (any value with a stable ``repr``: strings, numbers, tuples) of
    ``kind`` (a folder name), or None when the cache is disabled."""
    root = cache_dir()
    if root is None:
        return None
    name = hashlib.sha256(f"{code_fingerprint()}|{kind}|{key!r}".encode()).hexdigest()
    return root / kind / f"{name}.pickle"


def load(kind: str, key, expected: type):
    """The value kept for ``key`` of ``kind`` if it is an ``expected`` instance, else None."""
    path = path_for(kind, key)
    if path is None:
        return None
    try:
        with open(path, "rb") as f:
            value = pickle.load(f)
    except Exception:  # absent, unreadable or not a pickle of this code: computed again
        return None
    return value if isinstance(value, expected) else None


def save(kind: str, key, value) -> bool:
    """Keep ``value`` for ``key`` of ``kind``; False (and nothing written) when the cache is
    disabled, its folder cannot be written or the value does not pickle."""
    path = path_for(kind, key)
    if path is None:
        return False
    tmp = None
    try:
        data = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".pickle")
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
        return True
    except Exception:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
        return False
