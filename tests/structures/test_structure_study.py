"""Studies over structures (``structure:``): resolution to one mechanism and a categorical
design variable, the successive-halving schedule, runs (one process, workers, killed and
resumed), the final re-evaluation of every structure's best design and the report.

What is exact: the schedule's survivors against an independent ranking (the two-objective
hypervolume computed here as a staircase sum), the counts of designs per structure and rung,
the conditional dimensions, and a killed-and-resumed run equal to the uninterrupted one.
What is a trend only: nothing here depends on which structure is better.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from parasynth import structures
from parasynth.mechanisms import load_mechanism
from parasynth.study import StudyError, load_study, run_study
from parasynth.study.evaluate import Record
from parasynth.study.schedule import Schedule, structure_schedule
from parasynth.study.spec import check_study
from parasynth.study.structure_space import labels_of

KILLER = str(Path(__file__).resolve().parents[1] / "data" / "kill_at_trial.py")


def study_dict(**over):
    d = {
        "name": "structures_test",
        "structure": {"motion": "3T2R", "leg_types": ["UPS", "PUS", "RUS", "UPU"], "arrangements": ["paired"],
                      "reference": "5-PUS/UPU", "screening": 4, "eta": 2},
        "variables": [{"name": "base_radius", "low": "100 mm", "high": "150 mm"},
                      {"name": "platform_radius", "low": "40 mm", "high": "80 mm"},
                      {"name": "link_length", "low": "150 mm", "high": "205 mm"},
                      {"name": "height", "low": "200 mm", "high": "350 mm"}],
        "fixed": {"stroke": "205 mm", "slider_min": "0 mm", "q_min": "150 mm"},
        "objectives": [{"name": "workspace_volume", "label": "volume", "goal": "maximize"},
                       {"name": "singularity_margin_min", "label": "margin", "goal": "maximize",
                        "settings": {"quantile": 0.05}}],
        "constraints": [{"name": "footprint_radius", "label": "footprint", "max": "140 mm"}],
        "evaluation": {"samples": 256, "ranges": {"x": ["-200 mm", "200 mm"], "y": ["-200 mm", "200 mm"],
                                                  "z": ["0 mm", "600 mm"]},
                       "final_samples": 512, "final_repeats": 2, "final_top": 2},
        "optimizer": {"kind": "optuna", "n_trials": 8, "seed": 3},
    }
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(d.get(k), dict):
            d[k] = {**d[k], **v}
        else:
            d[k] = v
    return d


def resolved(**over):
    return load_study(yaml.safe_dump(study_dict(**over)), is_text=True)


# -- resolution ------------------------------------------------------------------------------------
def test_a_run_says_which_structures_it_compares(capsys):
    from parasynth import cli

    s = resolved()
    cli._say_structures(s, quiet=True)
    assert capsys.readouterr().err == ""
    cli._say_structures(s, quiet=False)
    err = capsys.readouterr().err.strip()
    setup = s.structures
    assert err.startswith(f"3T2R: {len(setup.labels)} structure(s) to compare, of {setup.enumerated} candidate(s)")
    assert "; reference 5-PUS/UPU: " in err and all(label in err for label in setup.labels)
    assert len(setup.labels) >= 2


def test_structure_is_a_categorical_variable_with_conditional_dimensions():
    s = resolved()
    found = [x for x in structures("3T2R", leg_types=["UPS", "PUS", "RUS", "UPU"]) if x.groups[0].arrangement == "paired"]
    assert s.structures.labels == tuple(labels_of(found)) == ("5-UPS/UPU", "5-PUS/UPU", "5-RUS/UPU")
    v = s.space.by_name["structure"]
    assert s.variables[0] is v and v.type == "categorical" and v.choices == s.structures.labels
    # link_length is a dimension of the limbs with a link of fixed length only (PUS, RUS)
    assert s.space.by_name["link_length"].when == (("structure", ("5-PUS/UPU", "5-RUS/UPU")),)
    assert s.space.by_name["base_radius"].when == ()
    # every part of a study builds the structure's mechanism by name: the same as the structure
    m = load_mechanism(s.mechanism, structure="5-UPS/UPU", base_radius=0.12)
    ref = found[0].mechanism(base_radius=0.12)
    X = ref.home + np.random.default_rng(0).normal(0, 0.01, (20, 5))
    np.testing.assert_allclose(m.inverse_kinematics(X).actuators, ref.inverse_kinematics(X).actuators, equal_nan=True)
    assert [leg.joints for leg in m.legs] == ["UPS"] * 5 + ["UPU"]
    assert check_study(s, measures=False) == []
    from parasynth.mechanisms import list_mechanisms

    assert s.mechanism not in list_mechanisms()  # registered for the study, not listed as a model
    # key paths name the study file's entries, not the resolved list (which starts with structure)
    assert s.variable_path("link_length") == "variables[2]" and s.variable_path("structure") == "structure"
    bad = resolved(variables=[{"name": "platform_radius", "low": "40 mm", "high": "80 mm"},
                              {"name": "base_radius", "low": "-100 mm", "high": "150 mm"}])
    assert any(p.startswith("variables[1].low") for p in check_study(bad, measures=False))
    # the study as run names the section, not the generated mechanism
    assert "structure:" in s.to_yaml() and "mechanism" not in yaml.safe_load(s.to_yaml())


@pytest.mark.parametrize("over,needle", [
    ({"mechanism": "5pus_upu"}, "mechanism: give either mechanism: or structure:, not both"),
    ({"structure": {"motion": "3X2R"}}, "structure.motion: motion must be written like"),
    ({"structure": {"leg_types": ["PUS", "XYZ"]}}, "structure.leg_types: unknown limb type 'XYZ'"),
    ({"structure": {"reference": "6-UPS"}}, "structure.reference: '6-UPS' is not any of the structures found"),
    ({"structure": {"include": ["5-SPS/UPU"]}}, "structure.include[0]: '5-SPS/UPU' is not among the structures"),
    ({"structure": {"arrangements": ["round"]}}, "structure.arrangements[0]: unknown arrangement 'round'"),
    ({"structure": {"leg_types": ["PUS", "UPU"]}}, "a study over structures needs at least two"),
    # 3T1R with every axis choice: rotations about x for some 2-UPU&2-UPS, about the moving y for others
    ({"structure": {"motion": "3T1R", "leg_types": ["UPU", "UPS"], "arrangements": None, "all_axes": True,
                    "reference": None}},
     "structure: the structures found move in different task coordinates: x, y, z, beta (axes: {translations: "
     "[x, y, z], rotations: [moving y]}: 2-UPU&2-UPS"),
    ({"structure": {"screening": 0}}, "structure.screening"),
    ({"optimizer": {"algorithm": "nsga2"}}, "a study over structures uses one of tpe, random"),
    ({"optimizer": {"kind": "nlopt", "n_trials": None}}, "use optimizer.kind: optuna"),
    ({"variables": [{"name": "base_offset_2", "low": "0 deg", "high": "10 deg"}]},
     "'base_offset_2' is used by none of the structures"),
    # empty selections are refused, never read as "every structure"
    ({"structure": {"include": []}}, "structure.include: an empty list would keep no structure"),
    ({"structure": {"arrangements": []}}, "structure.arrangements: an empty list would keep no structure"),
    ({"structure": {"axes": {}}}, "structure.axes must be a mapping"),
    ({"structure": {"leg_types": []}}, "structure.leg_types must name at least one limb type"),
    ({"structure": {"legs": [1000000]}}, "structure.legs must be at most 1000"),
    # halving settings the budget would clip or that would not act (n_trials 8, 3 structures)
    ({"structure": {"screening": 9}}, "structure.screening: 9 designs per structure in the first rung exceed "
                                      "the budget of 8"),
    ({"structure": {"screening": 8, "eta": 3}}, "structure.eta: the screening (8 designs) is already the whole "
                                                "budget"),
    ({"structure": {"screening": 8, "eta": 2, "keep": 1}}, "structure.eta: the screening"),
    ({"structure": {"keep": 3}}, "structure.keep: 3 structures continuing after each rung keep every one of the 3"),
    ({"optimizer": {"kind": "sweep", "n_trials": None, "seed": None, "designs": [{"base_radius": "120 mm"}]}},
     "structure.screening: successive halving spreads the trials of an Optuna study; a sweep"),
])
def test_bad_structure_sections_name_the_key(over, needle):
    with pytest.raises(StudyError) as e:
        resolved(**over)
    assert needle in str(e.value), str(e.value)


def test_the_study_does_not_depend_on_the_order_of_leg_types_or_include():
    """The same limb types or included structures in another order (or named twice) give the
    same structures in the same order, hence the same combined description (its registry name
    is a digest of it) and the same reference and first structure."""
    a = resolved()
    labels = list(a.structures.labels)
    assert len(labels) == 3
    from parasynth.structures import StructureWarning

    with pytest.warns(StructureWarning, match="^leg_types: UPS given more than once"):
        b = resolved(structure={"leg_types": ["UPU", "RUS", "PUS", "UPS", "UPS"]})
    c = resolved(structure={"include": list(reversed(labels))})
    for x in (b, c):
        assert x.mechanism == a.mechanism and list(x.structures.labels) == labels
        assert x.space.by_name["structure"].choices == a.space.by_name["structure"].choices


def test_halving_settings_that_act_are_accepted():
    """Three structures, 8 designs each at most: screening 4 -> rungs of 4 and 8 designs; keep 2
    of 3 halves; the defaults (screening 16 clipped to the budget) are not refused."""
    s = resolved(structure={"screening": 4, "eta": 2, "keep": 2})
    sch = structure_schedule(s)
    assert sch.targets == (4, 8) and len(s.space.by_name["structure"].choices) == 3
    d = study_dict()
    d["structure"] = {k: v for k, v in d["structure"].items() if k not in ("screening", "eta")}
    assert structure_schedule(load_study(yaml.safe_dump(d), is_text=True)).targets == (8,)
    # --n-trials below the screening would clip it: refused as the study file would be
    from parasynth.study.budget import with_budget

    assert structure_schedule(with_budget(s, 6)).targets == (4, 6)
    with pytest.raises(StudyError, match=r"^--n-trials 3: structure.screening: 4 designs per structure"):
        with_budget(s, 3)


# -- the schedule against an independent ranking ---------------------------------------------------------
class _Obj:
    def __init__(self, label, goal):
        self.label, self.goal = label, goal


def _staircase_hv(points, ref):
    """Hypervolume of 2-D minimisation points below ``ref``: the sum of the staircase's
    rectangles (independent of moocore)."""
    pts = [p for p in points if p[0] < ref[0] and p[1] < ref[1]]
    if not pts:
        return 0.0
    # sweep in x: the area is the integral over x of (ref_y - the least y of the points left of x)
    xs = sorted({p[0] for p in pts}) + [ref[0]]
    hv = 0.0
    for a, b in zip(xs[:-1], xs[1:]):
        hv += (b - a) * (ref[1] - min(p[1] for p in pts if p[0] <= a))
    return hv


def test_schedule_rungs_and_survivors_match_an_independent_ranking():
    rng = np.random.default_rng(4)
    labels = ["A", "B", "C", "D", "E"]
    objs = [_Obj("f", "maximize"), _Obj("g", "minimize")]
    sch = Schedule(labels, "E", screening=3, eta=2, n_full=10, objectives=objs)
    assert sch.targets == (3, 6, 10) and sch.max_total == 50
    quality = {"A": 0.2, "B": 1.0, "C": 0.6, "D": None, "E": 0.1}  # D: never feasible; E the reference
    recs, trial = [], 0

    def add(label, n):
        nonlocal trial
        for _ in range(n):
            q = quality[label]
            f, g = (rng.uniform(0, 1) * (q or 1), rng.uniform(0, 1) / (q or 1))
            recs.append(Record(values={"structure": label}, objectives={"f": f, "g": g},
                               margins={"c": -1.0 if q is None else 1.0}, trial=trial))
            trial += 1

    for lab in labels:
        add(lab, 2)
    p = sch.plan(recs)
    assert not p.done and p.current.index == 0 and p.total == 15 and p.counted == 10
    # a new design goes to the structure with the fewest, ties to the first; running ones count
    assert sch.next_structure(p, {}) == "A" and sch.next_structure(p, {"A": 1, "B": 1}) == "C"
    for lab in labels:
        add(lab, 1)
    p = sch.plan(recs)
    assert p.current.index == 1 and not p.done
    r0 = p.rungs[0]
    # independent ranking: normalise over the feasible designs of the rung, reference point 1.1
    feas = [r for r in recs if r.margins["c"] >= 0]
    F = np.array([[-r.objectives["f"], r.objectives["g"]] for r in feas])
    lo, hi = F.min(axis=0), F.max(axis=0)
    hv = {}
    for lab in labels:
        pts = [((-r.objectives["f"] - lo[0]) / (hi[0] - lo[0]), (r.objectives["g"] - lo[1]) / (hi[1] - lo[1]))
               for r in feas if r.values["structure"] == lab]
        hv[lab] = _staircase_hv(pts, (1.1, 1.1)) if pts else None
    assert r0.scores["D"] is None
    for lab in "ABCE":
        assert math.isclose(r0.scores[lab], hv[lab], rel_tol=1e-12, abs_tol=1e-15), lab
    best = sorted((lab for lab in "ABCE"), key=lambda s: -hv[s])[:3]  # ceil(5 / 2)
    assert set(p.current.alive) == set(best) | {"E"}
    assert "no feasible design" in r0.stopped["D"]
    for lab in set(labels) - set(best) - {"E", "D"}:
        assert "not among the best 3 of 5" in r0.stopped[lab]
    # the same records in another order give the same plan (decided by trial order, not arrival)
    assert sch.plan(list(reversed(recs))).current.alive == p.current.alive
    # structure.keep: that many continue (and the reference)
    one = Schedule(labels, "E", screening=3, eta=2, n_full=10, objectives=objs, keep=1).plan(recs)
    assert set(one.current.alive) == {best[0], "E"}
    for lab in set(labels) - {best[0], "E", "D"}:
        assert "not among the best 1 of 5" in one.rungs[0].stopped[lab]


def test_a_schedule_asked_again_with_more_records_plans_as_a_new_one(monkeypatch):
    """A run asks its schedule before every trial with the stored records (the same objects from
    call to call, the new ones after them); the schedule then reads only the new ones. Over a
    growing list, with records arriving out of trial order now and then (workers), a reference
    record, and records given in another order, every plan equals that of a new schedule given the
    same records (which reads them all), rungs, scores and survivors."""
    from parasynth.study import schedule as sched

    whole = []  # the calls that read every record (sorted them)
    monkeypatch.setattr(sched, "sorted", lambda it, **kw: (whole.append(1), sorted(it, **kw))[1], raising=False)
    rng = np.random.default_rng(11)
    labels = ["A", "B", "C", "D"]
    objs = [_Obj("f", "maximize"), _Obj("g", "minimize")]
    kept = Schedule(labels, "A", screening=3, eta=2, n_full=12, objectives=objs)
    recs, pending = [Record(values={"structure": "A"}, objectives={"f": 0.5, "g": 0.5}, trial=-1, source="reference")], []
    calls = 0
    for trial in range(60):
        lab = labels[int(rng.integers(len(labels)))]
        r = Record(values={"structure": lab}, objectives={"f": float(rng.uniform()), "g": float(rng.uniform())},
                   margins={"c": float(rng.uniform(-0.2, 1.0))}, trial=trial)
        if rng.uniform() < 0.15:
            pending.append(r)  # still running: stored later, before trials after it
            continue
        recs.append(r)
        if pending and rng.uniform() < 0.5:
            recs = sorted(recs + pending, key=lambda x: x.trial)  # as the storage gives them: in trial order
            pending = []
        got = kept.plan(recs)
        calls += 1
        want = Schedule(labels, "A", screening=3, eta=2, n_full=12, objectives=objs).plan(recs)
        assert got.counts == want.counts and got.done == want.done
        assert [(g.index, g.target, g.alive, g.scores, g.stopped) for g in got.rungs] == \
            [(w.index, w.target, w.alive, w.scores, w.stopped) for w in want.rungs]
        if trial % 7 == 0:  # another order: read whole, the same plan
            assert kept.plan(list(reversed(recs))).rungs == want.rungs
    # the kept schedule read every record only on its first call, after an insertion in the
    # middle and after a call in another order; the new schedules every time
    assert len(whole) < 2 * calls - 10


def test_a_structure_index_picks_the_trials_a_filter_would():
    """``StructureIndex.numbers`` (the trials of a structure, kept across calls) gives the trials
    that testing each one's structure attribute gives, in order, as trials are added: finished
    ones without a structure belong to none; a running one without its structure yet (just
    created by another process) is read again until it has one."""
    from types import SimpleNamespace

    from optuna.trial import TrialState

    from parasynth.study.optuna_adapter import StructureIndex

    rng = np.random.default_rng(5)
    trials, index = [], StructureIndex("s")
    for k in range(80):
        kind = rng.uniform()
        attrs = {} if kind < 0.1 else {"s": "AB"[int(rng.integers(2))]}
        state = TrialState.RUNNING if kind < 0.05 or rng.uniform() < 0.1 else TrialState.COMPLETE
        trials.append(SimpleNamespace(number=k, system_attrs=attrs, state=state))
        if rng.uniform() < 0.1:  # a running trial gets its structure, another finishes without one
            late = [t for t in trials if not t.system_attrs and t.state == TrialState.RUNNING]
            if late:
                late[0].system_attrs = {"s": "B"}
        for s in "AB":
            want = [t.number for t in trials if t.system_attrs.get("s") == s]
            assert index.numbers(trials, s) == want
    assert index._done > 40  # most trials classified once, not read again
    assert StructureIndex("s").numbers(list(reversed(trials)), "A") is None  # not in number order: the caller tests


# -- runs -------------------------------------------------------------------------------------------------
def _counts(table):
    run = table[table["source"] == "run"]
    return run.groupby("structure").size().to_dict()


def _compare(a: Path, b: Path):
    ta = pd.read_csv(a / "results.csv").drop(columns=["time_s"])
    tb = pd.read_csv(b / "results.csv").drop(columns=["time_s"])
    pd.testing.assert_frame_equal(ta, tb)


@pytest.fixture(scope="module")
def whole(tmp_path_factory):
    out = tmp_path_factory.mktemp("whole") / "run"
    s = resolved()
    res = run_study(s, out_dir=out, progress=False)
    return s, out, res


def test_a_run_follows_the_schedule(whole):
    s, out, res = whole
    t = res.table
    run = t[t["source"] == "run"].sort_values("trial")
    plan = structure_schedule(s).plan(res.new_records)
    assert plan.done and plan.counted == len(run)
    # screening: 4 designs of each structure, interleaved in enumeration order
    assert list(run["structure"][:12]) == list(s.structures.labels) * 4
    counts = _counts(t)
    full = plan.full()
    assert "5-PUS/UPU" in full  # the reference structure always continues
    for lab in s.structures.labels:
        assert counts[lab] == (8 if lab in full else plan.stopped_at()[lab][1])
    # inactive dimensions are absent: link_length only for the limbs with a link of fixed length
    assert run.loc[run["structure"] == "5-UPS/UPU", "link_length_m" if "link_length_m" in run else "link_length"].isna().all()
    # the final re-evaluation covers every structure's best design
    fin = pd.read_csv(out / "final.csv")
    assert set(s.structures.labels) <= set(fin.loc[fin["source"] == "best", "structure"])
    # the Optuna study names its objectives (optuna-dashboard shows them)
    import optuna

    from parasynth.study.storage import open_storage

    ostudy = optuna.load_study(study_name=s.name, storage=open_storage(f"journal:{out / 'optuna.journal'}"))
    assert ostudy.metric_names == ["volume", "margin"]


@pytest.mark.parametrize("change", ["other structure", "no structure"])
def test_report_and_export_refuse_a_journal_naming_a_structure_not_in_the_study(whole, tmp_path, change):
    """A design of a structure the study does not have (a journal edited or copied from another
    study) makes the run damaged: report and export stop, naming the journal and the trial; the
    intact copy is read."""
    import contextlib
    import io
    import json
    import shutil

    from parasynth.cli import main

    s, out, _ = whole
    run = tmp_path / "run"
    shutil.copytree(out, run, ignore=shutil.ignore_patterns("run.lock"))
    lines = (run / "journal.jsonl").read_text().splitlines()
    k, rec = next((i, json.loads(ln)) for i, ln in enumerate(lines) if json.loads(ln).get("source") == "run")
    if change == "other structure":
        rec["values"]["structure"] = "6-UPS"
        assert "6-UPS" not in s.structures.labels
    else:
        del rec["values"]["structure"]
    lines[k] = json.dumps(rec)
    (run / "journal.jsonl").write_text("\n".join(lines) + "\n")

    def cli(args):
        err = io.StringIO()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            try:
                code = main([str(a) for a in args])
            except SystemExit as e:
                code = e.code
        return code, err.getvalue()

    what = "names the structure '6-UPS'" if change == "other structure" else "names no structure"
    for args in (["report", run, "--out", tmp_path / "rep"], ["export", run, "--out", tmp_path / "best.xml"]):
        code, err = cli(args)
        assert code not in (0, None) and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
        assert f"journal.jsonl: the run design of trial {rec['trial']} {what}, not one of the study's " \
               f"structures ({', '.join(s.structures.labels)})" in err, err
    assert not (tmp_path / "best.xml").exists()
    code, err = cli(["export", out, "--out", tmp_path / "intact.xml"])
    assert code == 0 and (tmp_path / "intact.xml").is_file(), err


def test_report_has_the_structure_table_front_and_verdict(whole, tmp_path):
    from parasynth.report import write_report

    s, out, _ = whole
    rep = write_report(out, out=tmp_path / "rep")
    md = (rep / "report.md").read_text()
    assert "## Structures" in md and "**3 screened**" in md and "got the full budget" in md
    assert "| 5-PUS/UPU (reference) |" in md and "why designs failed" in md
    assert "## Reference structure 5-PUS/UPU" in md
    verdict = ("is on the combined front** (re-evaluated" in md) or ("is not on the combined front** (re-evaluated" in md)
    if not verdict:
        # Five limbs on a regular pentagon are singular at the symmetric home pose, whatever the radii:
        # no design passes verification, which the report says at the top and in the verdict.
        assert "**NO DESIGN PASSED VERIFICATION**" in md and "singularity margin at home" in md
        assert "**No verdict on 5-PUS/UPU**: none of its" in md
        from parasynth.study.design import design_mechanism
        from parasynth.study.rundir import read_run
        run = read_run(out)
        for _, r in run.final[run.final["source"] == "best"].iterrows():
            vals = {v.name: r[v.name] for v in s.variables if v.name in r and pd.notna(r[v.name])}
            mech = design_mechanism(s, s.space.restrict(vals) if s.space.conditional else vals)
            home = float(mech.singularity_margin(np.atleast_2d(mech.home), engine="numpy")[0])
            assert home < 1e-3 and not bool(r["verified"])  # independently: singular at home
    assert (rep / "img" / "structures.png").stat().st_size > 5000
    # the interactive view holds designs of several structures (each drawn with its own legs)
    import json
    import re

    page = (rep / "index.html").read_text()
    data = json.loads(re.search(r"<script type='application/json' id='viewer-data'>(.*?)</script>", page, re.S).group(1))
    assert "interactive view unavailable" not in md
    structures = {dict(d["values"]).get("structure") for d in data["designs"]}
    assert len(structures) >= 2 and all(len(d["C"]) > 1 for d in data["designs"])


def test_killed_runs_resume_the_same_schedule(whole, tmp_path):
    """SIGKILL at the first design of the second rung (while it is evaluated) and mid-rung,
    resumed each time: results.csv equals the uninterrupted run's (all but time_s)."""
    s, ref_out, _ = whole
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(study_dict()))
    out = tmp_path / "killed"
    for i, trial in enumerate((12, 15)):
        args = ["run", path, "--out", out, "--quiet", "--no-report"] + (["--resume"] if i else [])
        r = subprocess.run([sys.executable, KILLER, *map(str, args)], env={**os.environ,
                           "PARASYNTH_TEST_KILL": f"{trial}:evaluate"}, capture_output=True, text=True, timeout=300)
        assert r.returncode == -signal.SIGKILL, r.stderr
    res = run_study(load_study(path), out_dir=out, resume=True, progress=False)
    assert not res.interrupted
    _compare(out, ref_out)


def test_workers_complete_the_schedule(tmp_path):
    s = resolved(name="structures_workers")
    res = run_study(s, out_dir=tmp_path / "w", progress=False, workers=2)
    t = res.table[res.table["source"] == "run"]
    assert t["trial"].is_unique  # each trial once
    # a number missing from the table is a trial asked for by both workers for one last place
    # and refused unevaluated (workers.run_one_trial): failed and marked over budget
    import optuna
    from optuna.trial import TrialState

    from parasynth.study.storage import ATTR_OVER_BUDGET, open_storage

    stored = optuna.load_study(study_name=s.name, storage=open_storage("journal:" + str(tmp_path / "w" / "optuna.journal")))
    missing = set(range(int(t["trial"].max()) + 1)) - set(t["trial"])
    for tr in stored.trials:
        if tr.number in missing:
            assert tr.state == TrialState.FAIL and tr.user_attrs.get(ATTR_OVER_BUDGET) is True, tr.number
    assert missing <= {tr.number for tr in stored.trials}
    plan = structure_schedule(s).plan(res.new_records)
    assert plan.done
    for lab, n in _counts(res.table).items():
        target = 8 if lab in plan.full() else plan.stopped_at()[lab][1]
        assert n == target, (lab, n)  # a rung's last place goes to one worker only


def test_box_centre_is_at_the_reference_structure_with_its_dimensions():
    """The one design-space centre: the middle of each dimension's range, and for a study over
    structures its reference structure (not the first choice) with the dimensions it uses."""
    from parasynth.study.design import box_centre
    from parasynth.study.structure_space import STRUCTURE

    study = resolved()
    c = box_centre(study)
    assert c[STRUCTURE] == "5-PUS/UPU"
    choices = next(v.choices for v in study.variables if v.name == STRUCTURE)
    assert choices[0] != "5-PUS/UPU" or len(choices) == 1  # the reference is not merely the first choice
    assert c["base_radius"] == pytest.approx(0.125) and c["height"] == pytest.approx(0.275)
    assert set(c) == {v.name for v in study.space.active(c)}  # only the dimensions that structure uses


def test_stored_records_parsed_once_per_counted_trial(monkeypatch):
    """A structure study asks for every stored record before each trial: with the sampler's
    ``known`` dict each counted trial is parsed once, and the records are those parsed afresh
    (counted trials only: complete ones and failed ones with a record; not a running trial, nor a
    failed one without a record), as trials are added between the calls."""
    import optuna
    from optuna.distributions import FloatDistribution
    from optuna.trial import TrialState, create_trial

    from parasynth.study import storage, workers

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    ostudy = optuna.create_study(directions=["maximize"], study_name="records")

    def add(k, state, with_record=True, status="ok"):
        rec = Record(values={"structure": f"S{k % 3}", "x": float(k)}, objectives={"v": float(k)}, status=status)
        attrs = {storage.ATTR_RECORD: rec.to_dict()} if with_record else {}
        ostudy.add_trial(create_trial(state=state, params={"x": float(k)}, distributions={"x": FloatDistribution(0, 99)},
                                      values=[float(k)] if state == TrialState.COMPLETE else None, user_attrs=attrs))

    parsed = []
    real = workers.trial_record
    monkeypatch.setattr(workers, "trial_record", lambda t: (parsed.append(t.number), real(t))[1])
    known = {}

    def same(a, b):
        return [(r.trial, r.values, r.objectives, r.status) for r in a] == [(r.trial, r.values, r.objectives, r.status)
                                                                          for r in b]

    for k in range(5):
        add(k, TrialState.COMPLETE)
    add(5, TrialState.FAIL, status="failed")   # counted: a design that failed
    add(6, TrialState.FAIL, with_record=False)  # not counted: no record
    first = workers._stored_records(ostudy, known)
    assert [r.trial for r in first] == [0, 1, 2, 3, 4, 5]
    assert sorted(parsed) == [0, 1, 2, 3, 4, 5]
    parsed.clear()
    for k in range(7, 10):
        add(k, TrialState.COMPLETE)
    again = workers._stored_records(ostudy, known)
    assert sorted(parsed) == [7, 8, 9]  # only the new counted trials parsed
    parsed.clear()
    fresh = workers._stored_records(ostudy)
    assert len(parsed) == 9  # without ``known``: every counted trial parsed again
    assert same(again, fresh) and [r.trial for r in again] == [0, 1, 2, 3, 4, 5, 7, 8, 9]
    # the trials before the first one still running are read once; a running trial is read
    # again until it counts, and its record then comes in its place
    looked = []
    real_counts = workers.counts
    monkeypatch.setattr(workers, "counts", lambda t: (looked.append(t.number), real_counts(t))[1])
    running = ostudy.ask()  # trial 10
    for k in range(11, 13):
        add(k, TrialState.COMPLETE)
    got = workers._stored_records(ostudy, known)
    assert 10 in looked and not set(looked) & set(range(10))
    assert [r.trial for r in got] == [0, 1, 2, 3, 4, 5, 7, 8, 9, 11, 12] and same(got, workers._stored_records(ostudy))
    looked.clear()
    running.set_user_attr(storage.ATTR_RECORD, Record(values={"structure": "S1", "x": 10.0}, objectives={"v": 10.0}).to_dict())
    ostudy.tell(running, 10.0)
    got = workers._stored_records(ostudy, known)
    assert 10 in looked and not set(looked) & set(range(10))
    assert [r.trial for r in got] == [0, 1, 2, 3, 4, 5, 7, 8, 9, 10, 11, 12] and same(got, workers._stored_records(ostudy))
    looked.clear()
    add(13, TrialState.COMPLETE)
    got = workers._stored_records(ostudy, known)
    assert looked == [13] and [r.trial for r in got][-2:] == [12, 13]  # all before it final: not read again
