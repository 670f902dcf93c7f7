"""Enumerations kept on disk (parasynth.common.cache): a second ``structures`` call with the same
arguments reads the first one's answer instead of checking the candidates again, and that answer
is the first one in every field (and builds the same mechanisms); other arguments, another
engine or other code compute anew; a damaged file is computed again."""
from __future__ import annotations

import numpy as np
import pytest

from parasynth.common import cache
from parasynth.common.validation import numpy_reference
from parasynth.structures import synthesis
from parasynth.structures import structures


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", str(tmp_path / "c"))
    return tmp_path / "c"


@pytest.fixture
def checks(monkeypatch):
    """The number of candidate checks (``synthesis._verified`` calls) made since."""
    calls = []
    real = synthesis._verified

    def counted(jobs, processes):
        calls.append(len(jobs))
        return real(jobs, processes)

    monkeypatch.setattr(synthesis, "_verified", counted)
    return calls


def _fields(found):
    return (found.motion, found.enumerated, found.dropped, found.dropped_names, found.no_task_rule, found.no_home,
            [(s.name, s.key, s.label, s.groups, s.arrangement, s.template, s.axes, s.description, s.checked_poses,
              s.controlled_poses, s.home_margin, s.checked_margin, s.equivalents, s.verified) for s in found])


def test_a_second_enumeration_is_read_back_equal_to_the_first(folder, checks):
    """1T2R: parasitic motions, candidates without a home near the nominal one (with their
    reasons), several structures; the second answer comes without a single check and equals the
    first."""
    first = structures("1T2R", processes=1)
    assert len(checks) == 1 and first.no_home
    files = list((folder / "structures").iterdir())
    assert len(files) == 1
    second = structures("1T2R", processes=1)
    assert len(checks) == 1  # read back, nothing checked again
    assert second is not first and _fields(second) == _fields(first)
    assert second.summary() == first.summary()
    for a, b in zip(first, second):  # the model classes are built anew from the descriptions read back
        ma, mb = a.mechanism(), b.mechanism()
        assert type(mb) is not type(ma)
        np.testing.assert_array_equal(mb.home, ma.home)
        assert float(mb.singularity_margin(mb.home[None, :], engine="numpy")[0]) == \
            float(ma.singularity_margin(ma.home[None, :], engine="numpy")[0]) == a.home_margin


def test_other_arguments_engine_or_code_are_computed_again(folder, checks, monkeypatch):
    kw = dict(leg_types=["UPS", "SPS"], processes=1)
    base = structures("3T3R", **kw)
    assert base[0].equivalents  # the 6-SPS folded into the 6-UPS: kept with the answer
    structures("3T3R", **kw)
    assert len(checks) == 1
    structures("3T3R", seed=1, **kw)
    structures("3T3R", n_poses=2, **kw)
    structures("3T3R", leg_types=["SPS", "UPS"], processes=1)  # the same types: the same answer
    assert len(checks) == 3
    with numpy_reference():  # another engine: its own answer
        structures("3T3R", **kw)
    assert len(checks) == 4
    monkeypatch.setattr(cache, "code_fingerprint", lambda: "other code")
    again = structures("3T3R", **kw)
    assert len(checks) == 5 and _fields(again) == _fields(base)


def test_show_dropped_is_the_callers_and_a_damaged_file_is_computed_again(folder, checks):
    kw = dict(leg_types=["UPS", "SPS"], processes=1)
    quiet = structures("3T3R", **kw)
    loud = structures("3T3R", show_dropped=True, **kw)
    assert len(checks) == 1
    assert not quiet.show_dropped and loud.show_dropped
    assert loud.summary().startswith(quiet.summary()) and len(loud.summary()) > len(quiet.summary())
    (path,) = list((folder / "structures").iterdir())
    path.write_bytes(b"damaged")
    again = structures("3T3R", **kw)
    assert len(checks) == 2 and _fields(again) == _fields(quiet)
    assert structures("3T3R", **kw) is not None and len(checks) == 2  # written again, read back


def test_off_keeps_nothing(tmp_path, monkeypatch, checks):
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", "off")
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    structures("3T3R", leg_types=["UPS"], processes=1)
    structures("3T3R", leg_types=["UPS"], processes=1)
    assert len(checks) == 2 and not any(tmp_path.iterdir())


def test_a_limb_type_registered_since_import_is_computed_every_time(folder, checks, monkeypatch):
    """The cache's key holds parasynth's own code: a limb type registered or replaced at run time
    (a plugin's, ``register_limb``) is not in it, so an enumeration drawing on one is never kept."""
    import dataclasses

    from parasynth.structures import vocabulary

    own = dict(vocabulary.LIMB_TYPES)
    monkeypatch.setattr(vocabulary, "LIMB_TYPES", dict(own))
    monkeypatch.setattr(synthesis, "LIMB_TYPES", vocabulary.LIMB_TYPES)
    vocabulary.register_limb(dataclasses.replace(own["SPS"], arrangements=("regular",)))
    kw = dict(leg_types=["UPS", "SPS"], processes=1)
    a = structures("3T3R", **kw)
    b = structures("3T3R", **kw)
    assert len(checks) == 2 and _fields(a) == _fields(b)
    assert not (folder / "structures").exists()
    structures("3T3R", leg_types=["UPS"], processes=1)  # the own UPS alone: kept
    assert len(list((folder / "structures").iterdir())) == 1
