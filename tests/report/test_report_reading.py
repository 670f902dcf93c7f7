"""What the report explains to a designer: the meaning and scale of every unitless index where
the report first names the study's measures, design sketches at one scale, and a finding that is
a share stated in the verdict text."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import yaml

from parasynth.measures.objectives import OBJECTIVES
from parasynth.report.figures import Figures, plot_designs, sketch_boxes
from parasynth.report.render import analyse, load_run
from parasynth.report.sections import INDEX_MEANINGS, reading_text, sections, share_text
from parasynth.study import load_study
from parasynth.study.evaluate import Record


def _study(**changes):
    spec = {
        "name": "reading", "mechanism": "2rpu_2sps",
        "variables": [{"name": "b2", "values": ["350 mm", "400 mm", "450 mm"]},
                      {"name": "b4", "values": ["350 mm", "400 mm", "450 mm"]}],
        "objectives": [{"name": "usable_workspace_fraction", "label": "usable_share"},
                       {"name": "mean_lti"}],
        "reference": {"label": "the paper's design", "b2": "350 mm", "b4": "350 mm"},
        "evaluation": {"samples": 256},
        "optimizer": {"kind": "sweep"},
    }
    spec.update(changes)
    return load_study(yaml.safe_dump(spec), is_text=True)


#: Usable shares by hand: every symmetric layout (b2 = b4) keeps exactly one half; two of the
#: others keep all of their workspace, the rest between 20 % and 90 %.
SHARES = {(0.35, 0.35): 0.5, (0.35, 0.40): 0.2, (0.35, 0.45): 1.0, (0.40, 0.35): 0.9, (0.40, 0.40): 0.5,
          (0.40, 0.45): 0.3, (0.45, 0.35): 1.0, (0.45, 0.40): 0.6, (0.45, 0.45): 0.5}


def _records():
    recs = [Record(values={"b2": 0.35, "b4": 0.35}, objectives={"usable_share": 0.5, "mean_lti": 0.03},
                   trial=-1, source="reference", samples=256)]
    for k, ((b2, b4), share) in enumerate(SHARES.items()):
        recs.append(Record(values={"b2": b2, "b4": b4}, objectives={"usable_share": share, "mean_lti": 0.03 + 0.1 * share * (b2 != b4)},
                           trial=k, source="run", samples=256))
    return recs


def _run(tmp_path, study, final_rows=None):
    d = tmp_path / "run"
    d.mkdir()
    (d / "study.yaml").write_text(study.to_yaml())
    (d / "journal.jsonl").write_text("".join(json.dumps(r.to_dict()) + "\n" for r in _records()))
    if final_rows is not None:
        pd.DataFrame(final_rows).to_csv(d / "final.csv", index=False)
    run = load_run(d)
    return run, analyse(run)


# -- unitless indices ------------------------------------------------------------------------------
def test_every_unitless_measure_has_a_meaning_with_its_scale():
    unitless = {n for n, m in OBJECTIVES.items() if m.unit == "1"}
    assert unitless <= set(INDEX_MEANINGS), sorted(unitless - set(INDEX_MEANINGS))
    for name, text in INDEX_MEANINGS.items():
        assert text.endswith(".") and "\n" not in text, name
        assert any(w in text for w in ("0 ", "0.", " 1 ", " 1,", "1 (")), (name, text)  # a scale, in numbers


def test_the_summary_explains_the_unitless_measures_before_any_table(tmp_path):
    study = _study(objectives=[{"name": "singularity_margin_min", "label": "margin_q05", "settings": {"quantile": 0.05}},
                               {"name": "workspace_volume", "label": "volume"}],
                   constraints=[{"name": "min_lti", "min": 0.2}],
                   evaluation={"samples": 256, "constraints": [{"type": "singularity_margin", "min": 0.02}]})
    text = reading_text(study)
    assert "**margin_q05** (singularity_margin_min): the 5 % quantile of the singularity margin" in text
    assert "0 at a singularity" in text and "at most 1" in text
    assert "**min_lti**: the smallest local transmission index" in text and "0.7" in text
    assert "**singularity_margin**: a floor on the singularity margin of every pose counted" in text
    assert "volume" not in text.split("Reading the unitless measures:")[1].split("**")[1]  # a volume has a unit
    run, a = _run(tmp_path, _study())
    secs = sections(run, a)
    assert [x.title for x in secs[:2]] == ["Recommendation", "Summary"]
    assert secs[0].table is None and secs[1].table is None
    assert "**usable_share** (usable_workspace_fraction): the usable volume over the feasible volume" in secs[1].text
    assert "**mean_lti**: the mean local transmission index" in secs[1].text
    assert sum("Reading the unitless measures" in s.text for s in secs) == 1


def test_the_reading_paragraph_defines_a_measure_once():
    """A constraint on an objective's measure (the structure studies' margin_q05 and margin_min)
    is said to be that measure, and a definition several meanings share (the singularity margin,
    the local transmission index) is given once: the first measure of it defines it."""
    from parasynth.report.sections import _LTI, _MARGIN

    study = _study(objectives=[{"name": "singularity_margin_min", "label": "margin_q05", "settings": {"quantile": 0.05}},
                               {"name": "min_lti", "label": "lti"}],
                   constraints=[{"name": "singularity_margin_min", "label": "margin_min", "min": 0.001,
                                 "settings": {"quantile": 0.05}},
                                {"name": "mean_lti", "min": 0.3}],
                   evaluation={"samples": 256, "constraints": [{"type": "singularity_margin", "min": 0.02}]})
    text = reading_text(study)
    assert text.count(_MARGIN) == 1 and text.count(_LTI) == 1
    assert "**margin_min** (singularity_margin_min): the same measure as margin_q05." in text
    assert "**mean_lti**: the mean local transmission index over the workspace samples." in text
    assert "**singularity_margin**: a floor on the singularity margin of every pose counted." in text
    assert text.index(_MARGIN) < text.index("**margin_min**")


def test_a_study_without_unitless_measures_has_no_reading_paragraph():
    study = _study(objectives=[{"name": "workspace_volume", "label": "volume"},
                               {"name": "footprint_radius"}])
    assert reading_text(study) == ""


# -- shares in the verdict ---------------------------------------------------------------------------
def test_the_verdict_states_that_every_symmetric_layout_keeps_half(tmp_path):
    run, a = _run(tmp_path, _study())
    text = share_text(run, a)
    assert text.startswith("**Shares** (evaluated (single samples) values): **usable_share**: ")
    assert "every design with b2 = b4 (3 of the 9 evaluated (single samples) designs) keeps exactly 50 %" in text
    assert "2 of the 9 evaluated (single samples) designs keep exactly 100 % (trial 2 and trial 6)" in text
    assert "the other designs keep 20-90 %" in text
    assert "the paper's design 50 % (single sample)" in text
    ref = next(s for s in sections(run, a) if s.title == "The paper's design")
    assert text in ref.text


def test_the_share_verdict_uses_the_re_evaluated_values(tmp_path):
    rows = []
    for k, ((b2, b4), share) in enumerate(SHARES.items()):
        s = 0.5 if b2 == b4 else (share if share != 1.0 else 0.95 + 0.005 * k)  # the pair at 100 % splits
        rows.append({"source": "best", "trial": k, "b2": b2, "b4": b4, "usable_share": s, "usable_share_stderr": 0.0,
                     "mean_lti": 0.03, "mean_lti_stderr": 0.0, "feasible": True, "samples": 4096, "repeats": 1,
                     "knee": k == 3, "count": 1})
    rows.append({**rows[0], "source": "reference", "trial": -1, "knee": False})
    run, a = _run(tmp_path, _study(), rows)
    text = share_text(run, a)
    assert "(re-evaluated values)" in text
    assert "every design with b2 = b4 (3 of the 9 re-evaluated designs) keeps exactly 50 %" in text
    assert "keep exactly 100 %" not in text and "the other designs keep 20-98 %" in text
    knee = int(a.final.knee["trial"])
    want = {r["trial"]: r["usable_share"] for r in rows}[knee]
    assert f"the paper's design 50 %, the recommended design (trial {knee}) {100 * want:g} %" in text


def test_no_equal_variables_behind_a_group_lists_its_trials(tmp_path):
    study = _study()
    run, a = _run(tmp_path, study)
    a.runs.loc[a.runs["trial"] == 4, "usable_share"] = 0.45  # b2 = b4 = 400 mm no longer keeps half
    text = share_text(run, a)
    assert "every design with b2 = b4" not in text
    assert "2 of the 9 evaluated (single samples) designs keep exactly 50 % (trial 0 and trial 8)" in text


# -- design sketches at one scale --------------------------------------------------------------------
def test_sketch_boxes_are_cubes_of_one_side_around_each_design():
    pts = {"a": np.array([[0.0, 0, 0], [100, 20, 50]]), "b": np.array([[-300.0, 10, 0], [100, 30, 900]])}
    boxes = sketch_boxes(pts, pad=0.0)
    for n, (lo, hi) in boxes.items():
        np.testing.assert_allclose(hi - lo, 900.0)  # b's z extent, the largest of all
        np.testing.assert_allclose((lo + hi) / 2, (pts[n].min(0) + pts[n].max(0)) / 2)


def _pixels_per_mm(fig, ax, centre) -> np.ndarray:
    """Pixel lengths of 100 mm segments along X, Y and Z through ``centre`` in a 3D axes."""
    from mpl_toolkits.mplot3d import proj3d

    fig.canvas.draw()
    out = []
    for e in np.eye(3):
        a, b = centre - 50 * e, centre + 50 * e
        pa = ax.transData.transform(proj3d.proj_transform(*a, ax.get_proj())[:2])
        pb = ax.transData.transform(proj3d.proj_transform(*b, ax.get_proj())[:2])
        out.append(np.hypot(*(pb - pa)) / 100)
    return np.array(out)


def test_design_sketches_share_one_scale():
    """Two designs of very different size (base anchors 350 and 800 mm from the centre): each
    axis direction covers the same pixels per mm in both sketches."""
    study = _study(variables=[{"name": "b2", "low": "300 mm", "high": "900 mm"},
                              {"name": "b4", "low": "300 mm", "high": "900 mm"}],
                   optimizer={"kind": "optuna", "n_trials": 4})
    figs = Figures(keep=True)
    plot_designs(figs, study, {"small": {"b2": 0.35, "b4": 0.35}, "large": {"b2": 0.8, "b4": 0.8}})
    fig = figs.figures["designs"]
    axes = [ax for ax in fig.axes if ax.name == "3d"]
    assert len(axes) == 2
    scales = []
    for ax in axes:
        centre = np.array([np.mean(ax.get_xlim()), np.mean(ax.get_ylim()), np.mean(ax.get_zlim())])
        scales.append(_pixels_per_mm(fig, ax, centre))
    np.testing.assert_allclose(scales[0], scales[1], rtol=1e-6)
    spans = [(np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim()), np.ptp(ax.get_zlim())) for ax in axes]
    assert np.allclose(spans, spans[0][0]) and spans[0][0] > 1600  # the large design's 1.6 m base fits
    caption = next(c for n, c, _ in figs.items if n == "designs")
    assert "all at one scale" in caption
