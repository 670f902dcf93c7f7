"""Scrambled Sobol' points, kept on disk once drawn.

The points themselves come from ``scipy.stats.qmc.Sobol`` (scrambled, seeded); this module only
keeps them. Importing ``scipy.stats`` costs about 1.4 s on a 2-core machine, more than a whole
small study spends evaluating designs, and every study, ``validate`` and report asks for the
same few point sets (its ``evaluation.samples`` and ``seed`` in its dimension). So a point set
of at most :data:`DISK_MAX_BYTES` (16 MiB) is saved the first time it is drawn, as a ``.npy`` file under
the cache folder, and read back (bit for bit the same numbers) by later processes, which then
never import ``scipy.stats``.

The cache folder is ``$PARASYNTH_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/parasynth``, else
``~/.cache/parasynth``; ``PARASYNTH_CACHE_DIR=off`` disables it. The file name holds the SciPy
version, the dimension, the seed and the number of points, so a SciPy upgrade draws anew. A
file that cannot be read or has the wrong shape is drawn again and replaced; a folder that
cannot be written is skipped silently (the points are drawn every time, as without a cache).
"""
from __future__ import annotations

import functools
import inspect
import os
import tempfile
import warnings
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

#: Largest point set (bytes of float64) kept on disk; larger ones are drawn block by block every
#: time, so that a very large workspace streams in bounded memory.
DISK_MAX_BYTES = 16 * 2**20

__all__ = ["sobol_engine", "sobol_points", "cache_dir", "DISK_MAX_BYTES"]


def cache_dir() -> Path | None:
    """The folder of the point cache, or None when disabled (``PARASYNTH_CACHE_DIR=off``)."""
    env = os.environ
    return _cache_dir(env.get("PARASYNTH_CACHE_DIR"), env.get("XDG_CACHE_HOME"), env.get("HOME"))


@functools.lru_cache(maxsize=8)
def _cache_dir(env: str | None, xdg: str | None, home: str | None) -> Path | None:
    """:func:`cache_dir` for these values of the variables it reads (kept: resolving the
    home folder costs ~0.1 ms, a fifth of drawing a new set of 8192 points)."""
    if env is not None:
        return None if env.strip().lower() in ("", "off", "0", "none") else Path(env).expanduser()
    return (Path(xdg) if xdg else Path.home() / ".cache") / "parasynth"


@functools.lru_cache(maxsize=1)
def _sobol_takes_rng() -> bool:
    """Whether ``qmc.Sobol`` takes ``rng`` (SciPy >= 1.15) rather than ``seed`` (asked once)."""
    from scipy.stats import qmc  # lazy: scipy.stats takes ~1.4 s to import

    return "rng" in inspect.signature(qmc.Sobol).parameters


def sobol_engine(d: int, seed: int, n: int):
    """A scrambled ``scipy.stats.qmc.Sobol`` engine of dimension ``d`` seeded with ``seed``
    (64-bit directions when ``n`` exceeds 2**30)."""
    from scipy.stats import qmc  # lazy: scipy.stats takes ~1.4 s to import

    kw: dict[str, Any] = {"scramble": True}
    if n > 2**30:
        kw["bits"] = 64
    if _sobol_takes_rng():
        kw["rng"] = seed
    else:  # pragma: no cover - scipy < 1.15
        kw["seed"] = seed
    return qmc.Sobol(d, **kw)


def _draw(d: int, seed: int, n: int) -> np.ndarray:
    eng = sobol_engine(d, seed, n)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*balance properties of Sobol.*")
        if n & (n - 1) == 0:
            return eng.random_base2(int(n).bit_length() - 1)
        return eng.random(n)


@functools.lru_cache(maxsize=1)
def _scipy_version() -> str:
    """SciPy's version, read once: ``importlib.metadata.version`` scans the installed
    distributions (~2 ms a call, more than drawing 8192 points)."""
    return metadata.version("scipy")


def _path(folder: Path, d: int, seed: int, n: int) -> Path:
    return folder / "sobol" / f"scipy-{_scipy_version()}" / f"d{d}-seed{seed}-n{n}.npy"


def sobol_points(d: int, seed: int, n: int) -> np.ndarray | None:
    """The first ``n`` points (n, d) of the scrambled Sobol' sequence of ``sobol_engine(d,
    seed, n)``, read from the disk cache when there, else drawn (and saved). None when the set
    is larger than :data:`DISK_MAX_BYTES`: draw those from :func:`sobol_engine` in blocks."""
    if n * d * 8 > DISK_MAX_BYTES:
        return None
    folder = cache_dir()
    path = _path(folder, d, seed, n) if folder is not None else None
    if path is not None and path.is_file():
        try:
            u = np.load(path, mmap_mode="r", allow_pickle=False)
            if u.shape == (n, d) and u.dtype == np.float64:
                return u
        except (OSError, ValueError):
            pass
    u = _draw(d, seed, n)
    if path is not None:
        _save(path, u)
    return u


#: Folders of the cache this process has made sure exist (a folder removed meanwhile makes the
#: write fail with OSError: it is then made again at the next write).
_MADE: set = set()


def _save(path: Path, u: np.ndarray) -> None:
    """Write ``u`` to ``path`` atomically (a temporary file renamed); a folder that cannot be
    written is skipped. Written here, not by a thread: a writer thread woken for every new set
    took the interpreter lock from the caller for milliseconds (the switch interval), more
    than the ~0.2 ms the write costs."""
    tmp = None
    try:
        if path.parent not in _MADE:
            path.parent.mkdir(parents=True, exist_ok=True)
            _MADE.add(path.parent)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            np.save(f, u, allow_pickle=False)
        os.replace(tmp, path)
    except OSError:
        _MADE.discard(path.parent)
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
