"""The Sobol' point cache: the same numbers as SciPy's engine, read back from disk without
importing scipy.stats, redrawn when the file is damaged, off when asked."""
from __future__ import annotations

import json
import subprocess
import sys
import warnings

import numpy as np
import pytest
from scipy.stats import qmc

from parasynth.common import qmc as pqmc


def _scipy_points(d, seed, n):
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*balance properties of Sobol.*")
        return qmc.Sobol(d, scramble=True, rng=seed).random(n)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


@pytest.mark.parametrize("d,seed,n", [(3, 0, 4096), (5, 7, 1000), (1, 3, 1)])
def test_points_are_scipys_and_come_back_from_disk(cache, monkeypatch, d, seed, n):
    u = pqmc.sobol_points(d, seed, n)
    assert np.array_equal(u, _scipy_points(d, seed, n))
    files = list(cache.rglob("*.npy"))
    assert len(files) == 1 and f"d{d}-seed{seed}-n{n}" in files[0].name

    def no_draw(*a):
        raise AssertionError("drawn again although cached")

    monkeypatch.setattr(pqmc, "_draw", no_draw)
    assert np.array_equal(pqmc.sobol_points(d, seed, n), u)


def test_a_damaged_file_is_drawn_again(cache):
    u = pqmc.sobol_points(2, 1, 64)
    (f,) = cache.rglob("*.npy")
    f.write_bytes(b"not an array")
    assert np.array_equal(pqmc.sobol_points(2, 1, 64), u)
    np.save(f, np.zeros((3, 2)))  # wrong shape
    assert np.array_equal(pqmc.sobol_points(2, 1, 64), u)
    assert np.load(f).shape == (64, 2)


def test_off_and_too_large(tmp_path, monkeypatch):
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", "off")
    assert pqmc.cache_dir() is None
    assert np.array_equal(pqmc.sobol_points(2, 0, 16), _scipy_points(2, 0, 16))
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(pqmc, "DISK_MAX_BYTES", 100)
    assert pqmc.sobol_points(2, 0, 16) is None
    assert not list(tmp_path.rglob("*.npy"))


def test_unwritable_folder_still_gives_the_points(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", str(blocker / "below"))
    assert np.array_equal(pqmc.sobol_points(3, 2, 32), _scipy_points(3, 2, 32))


_PROBE = """
import json, sys
from parasynth import workspace
from parasynth.mechanisms import load_mechanism
m = load_mechanism("5pus_upu")
w = workspace(m, ranges={"x": (-0.2, 0.2), "y": (-0.2, 0.2)}, n=2048, method="sobol", seed=5,
              engine="numpy")
print(json.dumps({"volume": w.volume, "stats": "scipy.stats" in sys.modules}))
"""


def _probe(env):
    out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_warm_workspace_does_not_import_scipy_stats(tmp_path):
    import os

    env = dict(os.environ, PARASYNTH_CACHE_DIR=str(tmp_path / "c"))
    first = _probe(env)
    second = _probe(env)
    off = _probe(dict(env, PARASYNTH_CACHE_DIR="off"))
    assert first["stats"] and off["stats"]
    assert not second["stats"]
    assert first["volume"] == second["volume"] == off["volume"] > 0


def test_a_folder_removed_after_a_write_is_made_again(cache):
    import shutil

    u = pqmc.sobol_points(2, 11, 32)
    assert list(cache.rglob("*.npy"))
    shutil.rmtree(cache)  # the process remembers the folder; the next write fails once
    v = pqmc.sobol_points(2, 12, 32)
    assert np.array_equal(v, _scipy_points(2, 12, 32))
    w = pqmc.sobol_points(2, 13, 32)  # ... and then the folder is made again
    assert np.array_equal(w, _scipy_points(2, 13, 32))
    assert [f.name for f in cache.rglob("*.npy")] == ["d2-seed13-n32.npy"]
    assert np.array_equal(pqmc.sobol_points(2, 11, 32), u)


def test_cache_dir_follows_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", str(tmp_path / "a"))
    assert pqmc.cache_dir() == tmp_path / "a"
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", str(tmp_path / "b"))
    assert pqmc.cache_dir() == tmp_path / "b"
    monkeypatch.delenv("PARASYNTH_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "x"))
    assert pqmc.cache_dir() == tmp_path / "x" / "parasynth"


@pytest.mark.parametrize("shape", [(8192, 3), (1, 1), (1000, 5)])
def test_saved_file_is_the_file_np_save_writes(tmp_path, shape):
    """The cache writes the header and the data itself: the same bytes as ``np.save``, no
    temporary file left behind, and an existing file replaced."""
    u = np.random.default_rng(3).random(shape)
    target = tmp_path / "sub" / "points.npy"
    pqmc._save(target, np.zeros(shape))
    pqmc._save(target, u)
    np.save(tmp_path / "ref.npy", u)
    assert target.read_bytes() == (tmp_path / "ref.npy").read_bytes()
    assert [f.name for f in target.parent.iterdir()] == ["points.npy"]
    assert np.array_equal(np.load(target), u)


@pytest.mark.parametrize("d", [1, 2, 3, 5, 6, 12])
def test_the_fast_draw_gives_scipys_points_bit_for_bit(d):
    assert pqmc._fast_sobol_ok(d)
    for seed in (0, 1, 99, 2**40 + 3, 2**63 + 5):
        for n in (0, 1, 2, 7, 8192, 10_000):
            u = pqmc._fast_sobol(d, seed, n)
            assert u.shape == (n, d) and u.dtype == np.float64
            assert u.tobytes() == _scipy_points(d, seed, n).tobytes(), (d, seed, n)


def test_a_fast_draw_that_disagrees_with_scipy_is_not_used(monkeypatch):
    pqmc._fast_sobol_ok.cache_clear()
    real = pqmc._fast_sobol
    monkeypatch.setattr(pqmc, "_fast_sobol", lambda d, seed, n: real(d, seed + 1, n))  # SciPy changed its ways
    try:
        assert not pqmc._fast_sobol_ok(4)
        assert np.array_equal(pqmc._draw(4, 5, 64), _scipy_points(4, 5, 64))
    finally:
        pqmc._fast_sobol_ok.cache_clear()
