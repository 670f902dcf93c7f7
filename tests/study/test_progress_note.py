"""The progress bar's note (the best value so far) is computed only for a bar that is shown, at
most every ``NOTE_EVERY`` seconds, and the last one when the bar closes."""

from __future__ import annotations

import io

import pytest

from parasynth.study import progress

tqdm = pytest.importorskip("tqdm").tqdm


def test_a_bar_not_shown_never_computes_its_note():
    bar = progress.Progress(10, True, "study")  # not a terminal here: tqdm shows nothing
    calls = []
    for k in range(10):
        bar.update(None, lambda k=k: calls.append(k) or f"{k} feasible")
    bar.close()
    assert calls == []


def test_a_shown_bar_computes_its_note_at_most_every_interval_and_the_last_one_at_close(monkeypatch):
    out = io.StringIO()
    bar = progress.Progress(10, False, "study")
    bar.bar = tqdm(total=10, file=out, disable=False, mininterval=0)
    clock = iter([0.0, 0.1, 0.2, 0.7, 0.8])
    monkeypatch.setattr(progress.time, "monotonic", lambda: next(clock))
    calls = []
    for k in range(5):
        bar.update(None, lambda k=k: calls.append(k) or f"{k} feasible")
    assert calls == [0, 3]  # at 0.0 s and 0.7 s (NOTE_EVERY = 0.5 s)
    bar.close()
    assert calls == [0, 3, 4]  # the last note, computed once when the bar closes
    assert "4 feasible" in out.getvalue()
