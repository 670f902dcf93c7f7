"""Results kept on disk (parasynth.common.cache): a value saved comes back equal, under a name
that changes with the key, the kind and the code; damaged files, other objects, a disabled or
unwritable cache all fall back to computing, without an error."""
from __future__ import annotations


import numpy as np
import pytest

from parasynth.common import cache


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", str(tmp_path / "c"))
    return tmp_path / "c"


def test_a_saved_value_comes_back_equal_and_nothing_else_is_left(folder):
    value = {"a": [1.5, np.arange(4)], "b": ("x", None)}
    assert cache.load("k", ("key", 1), dict) is None
    assert cache.save("k", ("key", 1), value)
    back = cache.load("k", ("key", 1), dict)
    assert back is not value and back["b"] == value["b"] and back["a"][0] == 1.5
    np.testing.assert_array_equal(back["a"][1], value["a"][1])
    files = sorted(p.name for p in (folder / "k").iterdir())
    assert files == [cache.path_for("k", ("key", 1)).name]  # no temporary file left
    # another key, another kind, another expected type: absent
    assert cache.load("k", ("key", 2), dict) is None
    assert cache.load("other", ("key", 1), dict) is None
    assert cache.load("k", ("key", 1), list) is None


def test_the_name_follows_the_code(folder, monkeypatch):
    before = cache.path_for("k", "x")
    assert cache.code_fingerprint() == cache.code_fingerprint()
    with monkeypatch.context() as m:
        m.setattr(np, "__version__", np.__version__ + ".other")
        cache.code_fingerprint.cache_clear()
        try:
            assert cache.path_for("k", "x") != before
        finally:
            cache.code_fingerprint.cache_clear()
    assert cache.path_for("k", "x") == before


def test_a_damaged_file_counts_as_absent(folder):
    assert cache.save("k", "x", [1, 2])
    path = cache.path_for("k", "x")
    path.write_bytes(b"\x80\x04not a pickle")
    assert cache.load("k", "x", list) is None
    path.write_bytes(b"")
    assert cache.load("k", "x", list) is None
    assert cache.save("k", "x", [3])  # replaced
    assert cache.load("k", "x", list) == [3]


def test_off_and_unwritable_folders_keep_nothing_and_raise_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", "off")
    assert cache.path_for("k", "x") is None
    assert cache.save("k", "x", [1]) is False and cache.load("k", "x", list) is None
    blocked = tmp_path / "file"
    blocked.write_text("a file where the folder would be")
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", str(blocked))
    assert cache.save("k", "x", [1]) is False
    assert cache.load("k", "x", list) is None
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", str(tmp_path / "ok"))
    assert cache.save("k", "x", lambda: 0) is False  # does not pickle
    assert not (tmp_path / "ok").exists()
