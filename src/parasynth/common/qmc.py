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
import io
import itertools
import os
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
    if n <= 2**30 and _fast_sobol_ok(d):
        return _fast_sobol(d, seed, n)
    eng = sobol_engine(d, seed, n)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*balance properties of Sobol.*")
        if n & (n - 1) == 0:
            return eng.random_base2(int(n).bit_length() - 1)
        return eng.random(n)


_POW30 = 2 ** np.arange(30, dtype=np.uint32)


def _fast_sobol(d: int, seed: int, n: int) -> np.ndarray:
    """The first ``n`` points of ``sobol_engine(d, seed, n)`` (30-bit directions), drawn by the
    compiled routines of SciPy's own ``Sobol`` (``scipy.stats._sobol``), the steps of its
    constructor and ``random`` without their checks and the copy of the generator kept for
    ``reset``: ~0.25 ms for 8192 points in 3-D against ~0.36 ms. The generator is the one
    ``Sobol(rng=seed)`` owns (spawned from ``default_rng(seed)``), consumed in the same order
    (the digital shift, then the scrambling matrices). :func:`_fast_sobol_ok` compares it with
    ``qmc.Sobol`` once per process and dimension; ``tests/common/test_qmc.py`` bit for bit over
    dimensions, seeds and sizes."""
    from scipy.stats._sobol import _cscramble, _draw as _sobol_draw, _initialize_v

    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed).spawn(1)[0]))
    sv = np.zeros((d, 30), dtype=np.uint32)
    _initialize_v(sv, dim=d, bits=30)
    shift = np.dot(rng.integers(0, 2, size=(d, 30), dtype=np.uint32), _POW30)
    ltm = np.tril(rng.integers(0, 2, size=(d, 30, 30), dtype=np.uint32))
    _cscramble(dim=d, bits=30, ltm=ltm, sv=sv)
    scale = 1.0 / 2**30
    out = np.empty((n, d))
    if n:
        out[0] = (shift * scale).astype(np.float64)
    if n > 1:
        _sobol_draw(n=n - 1, num_gen=0, dim=d, scale=scale, sv=sv, quasi=shift.copy(), sample=out[1:])
    return out


@functools.lru_cache(maxsize=64)
def _fast_sobol_ok(d: int) -> bool:
    """Whether :func:`_fast_sobol` gives ``qmc.Sobol``'s points in dimension ``d`` with this
    SciPy (checked once: 33 points of two seeds); else every set is drawn by ``qmc.Sobol``."""
    if not _sobol_takes_rng():  # pragma: no cover - scipy < 1.15 seeds differently
        return False
    try:
        for seed in (0, 2**40 + 7):
            eng = sobol_engine(d, seed, 33)
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", message=".*balance properties of Sobol.*")
                want = eng.random(33)
            if _fast_sobol(d, seed, 33).tobytes() != want.tobytes():
                return False
        return True
    except Exception:  # noqa: BLE001 - SciPy's private routines moved or changed: the public way
        return False


@functools.lru_cache(maxsize=1)
def _scipy_version() -> str:
    """SciPy's version, read once: ``importlib.metadata.version`` scans the installed
    distributions (~2 ms a call, more than drawing 8192 points)."""
    return metadata.version("scipy")


def _path(folder: Path, d: int, seed: int, n: int) -> str:
    return os.path.join(_version_dir(folder), f"d{d}-seed{seed}-n{n}.npy")


@functools.lru_cache(maxsize=8)
def _version_dir(folder: Path) -> str:
    """The folder of this SciPy version's point sets (a string: joining ``Path`` objects for
    every new set cost ~0.02 ms)."""
    return os.path.join(os.fspath(folder), "sobol", f"scipy-{_scipy_version()}")


def sobol_points(d: int, seed: int, n: int) -> np.ndarray | None:
    """The first ``n`` points (n, d) of the scrambled Sobol' sequence of ``sobol_engine(d,
    seed, n)``, read from the disk cache when there, else drawn (and saved). None when the set
    is larger than :data:`DISK_MAX_BYTES`: draw those from :func:`sobol_engine` in blocks."""
    if n * d * 8 > DISK_MAX_BYTES:
        return None
    folder = cache_dir()
    path = _path(folder, d, seed, n) if folder is not None else None
    if path is not None and os.path.isfile(path):
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
_TMP = itertools.count()


@functools.lru_cache(maxsize=16)
def _npy_header(shape: tuple, descr: str) -> bytes:
    """The ``.npy`` header (format 1.0) of a C-ordered array of ``shape`` and dtype ``descr``,
    the bytes ``np.save`` writes before the data."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": descr, "fortran_order": False, "shape": shape})
    return buf.getvalue()


def _save(path, u: np.ndarray) -> None:
    """Write ``u`` to ``path`` atomically (a temporary file of this process renamed); a folder
    that cannot be written is skipped. The header is made once per shape and the data written
    as one block: the file ``np.save`` would write, in ~0.05 ms for 8192 points in 3-D against
    ~0.14 ms by ``np.save`` into a ``tempfile.mkstemp`` file. Written here, not by a thread: a
    writer thread woken for every new set took the interpreter lock from the caller for
    milliseconds (the switch interval), more than the write costs."""
    path = os.fspath(path)
    folder = os.path.dirname(path)
    tmp = f"{path}.{os.getpid()}-{next(_TMP)}.tmp"
    fd = None
    try:
        if folder not in _MADE:
            os.makedirs(folder, exist_ok=True)
            _MADE.add(folder)
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        a = np.ascontiguousarray(u)
        head = _npy_header(a.shape, np.lib.format.dtype_to_descr(a.dtype))
        for part in (head, memoryview(a).cast("B")):
            view = memoryview(part)
            while view.nbytes:
                view = view[os.write(fd, view):]
        os.close(fd)
        fd = None
        os.replace(tmp, path)
    except OSError:
        _MADE.discard(folder)
        if fd is not None:
            os.close(fd)
        try:
            os.unlink(tmp)
        except OSError:
            pass
