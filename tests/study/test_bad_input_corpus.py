"""A corpus of malformed inputs generated from the shipped files by mutation.

Studies (``studies/*.yaml``), mechanism descriptions (``src/parasynth/mechanisms/*.yaml``),
command-line arguments and Python API calls. Each case asserts a clear refusal: no traceback,
a non-zero exit status (or a ``ValueError``) and the key path (or field) named in the
message. The study cases are exactly the ones ``parasynth run`` would reject or fail every
design on, so each also checks that ``validate`` refuses what ``run`` would reject. Documented
acceptances (docs/study-format.md) are asserted as accepted.

The CLI cases run ``parasynth.cli.main`` in-process; a handful use a subprocess.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import io
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

import parasynth
from parasynth.cli import main
from parasynth.study import load_study
from parasynth.study.spec import RESERVED_COLUMNS

ROOT = Path(__file__).resolve().parents[2]
STUDY_FILES = sorted((ROOT / "studies").glob("*.yaml"))
DESC_FILES = sorted((ROOT / "src" / "parasynth" / "mechanisms").glob("*.yaml"))
assert len(STUDY_FILES) >= 5 and len(DESC_FILES) >= 5


def run_cli(args):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in args])
        except SystemExit as e:
            code = e.code
    return code, out.getvalue(), err.getvalue()


def assert_refused(code, err, *needles):
    assert "Traceback" not in err, err
    assert code not in (0, None), f"accepted: {err}"
    assert err.strip(), "no message"
    for n in needles:
        assert n in err, f"{n!r} not named in: {err}"


# -- studies ------------------------------------------------------------------------------------
def _load(path):
    """A shipped study as a mapping, its task's files made absolute (the mutated copies are written
    elsewhere)."""
    d = yaml.safe_load(path.read_text())

    def absolute(m):
        if isinstance(m, dict):
            return {k: (str(path.parent / v) if k == "file" and isinstance(v, str) else absolute(v)) for k, v in m.items()}
        if isinstance(m, list):
            return [absolute(v) for v in m]
        return m

    if isinstance(d, dict) and "task" in d:
        d["task"] = absolute(d["task"])
    return d


def _unit_of(value):
    """'160 mm' -> 'mm'; a number -> None."""
    if isinstance(value, str):
        parts = value.split()
        return parts[1] if len(parts) == 2 else None
    return None


def _param_kinds(mech_name):
    from parasynth.mechanisms import mechanism_class

    return dict(getattr(mechanism_class(mech_name).Params, "UNITS", {}))


def _study_mutations(path, si=0):
    """(case id, mutated YAML text, key path that the message must name). Families of similar
    values (reserved labels, bad quantiles, ...) are spread over the studies (``si``: the
    study's index) so that the corpus covers them all without repeating each everywhere."""
    base = _load(path)

    def pick(seq, k=2):
        seq = list(seq)
        if len(seq) <= k:
            return seq
        return [seq[(si * k + j) % len(seq)] for j in range(k)]

    text0 = path.read_text()
    kinds = _param_kinds(base["mechanism"] if "mechanism" in base else load_study(path).mechanism)  # or structure:
    out = []

    def add(cid, fn, needle):
        d = copy.deepcopy(base)
        r = fn(d)
        if r is False:
            return
        out.append((f"{path.stem}:{cid}", yaml.safe_dump(d, sort_keys=False), needle))

    def add_text(cid, text, needle):
        out.append((f"{path.stem}:{cid}", text, needle))

    variables = base.get("variables", [])
    bounded = [i for i, v in enumerate(variables) if "low" in v and "high" in v]
    length_vars = [i for i in bounded if kinds.get(variables[i]["name"]) == "length"]
    unit_vars = [i for i in bounded if kinds.get(variables[i]["name"]) in ("length", "angle")]

    # top level
    add("unknown-top-key", lambda d: d.update(objective=[]), "objective")
    add("missing-name", lambda d: d.pop("name"), "name")
    add("bad-name", lambda d: d.update(name="has space"), "name")
    add("unknown-mechanism", lambda d: d.update(mechanism="nope_mech"), "mechanism")
    add("mechanism-list", lambda d: d.update(mechanism=[1]), "mechanism")
    add("no-objectives", lambda d: d.update(objectives=[]), "objectives")
    add("variables-mapping", lambda d: d.update(variables={"a": 1}), "variables")
    add("output-empty", lambda d: d.update(output=""), "output")
    add("description-number", lambda d: d.update(description=["a"]), "description")
    # variables
    if variables:
        add("var-unknown-param", lambda d: d["variables"][0].update(name="nope_param"), "variables[0].name")
        add("var-unknown-key", lambda d: d["variables"][0].update(lo="1 mm"), "variables[0].lo")
        add("var-bad-type", lambda d: d["variables"][0].update(type="real"), "variables[0].type")
        add("var-twice", lambda d: d["variables"].append(copy.deepcopy(d["variables"][0])), "variables[")
    for i in unit_vars[:1]:
        v = variables[i]
        u = _unit_of(v["low"])
        p = f"variables[{i}]"
        add(f"{p}-bare-low", lambda d, i=i: d["variables"][i].update(low=150), f"{p}.low")
        add(f"{p}-bool-low", lambda d, i=i: d["variables"][i].update(low=True), f"{p}.low")
        add(f"{p}-nan-low", lambda d, i=i, u=u: d["variables"][i].update(low=f"nan {u}"), f"{p}.low")
        add(f"{p}-inf-high", lambda d, i=i, u=u: d["variables"][i].update(high=f"inf {u}"), f"{p}.high")
        add(f"{p}-wrong-dim", lambda d, i=i: d["variables"][i].update(low="2 kg"), f"{p}.low")
        add(f"{p}-unparsable", lambda d, i=i: d["variables"][i].update(high="two metres"), f"{p}.high")
        add(f"{p}-swapped", lambda d, i=i: d["variables"][i].update(low=v["high"], high=v["low"]), p)
        add(f"{p}-empty", lambda d, i=i: d["variables"][i].update(high=v["low"]), p)
    for i in length_vars[:1]:
        p = f"variables[{i}]"
        add(f"{p}-neg-low", lambda d, i=i: d["variables"][i].update(low="-10 mm"), f"{p}.low")
        add(f"{p}-zero-low", lambda d, i=i: d["variables"][i].update(low="0 mm"), f"{p}.low")
    if bounded:
        i = bounded[0]
        add("var-num-zero", lambda d: d["variables"][i].update(num=0), f"variables[{i}].num")
        add("var-num-huge", lambda d: d["variables"][i].update(num=10**9), f"variables[{i}].num")
        add("var-log-bool", lambda d: d["variables"][i].update(log="maybe"), f"variables[{i}].log")
    # evaluation
    ev = base.get("evaluation", {})
    add("ev-seed-neg", lambda d: d.setdefault("evaluation", {}).update(seed=-1), "evaluation.seed")
    add("ev-seed-bool", lambda d: d.setdefault("evaluation", {}).update(seed=True), "evaluation.seed")
    add("ev-seed-huge", lambda d: d.setdefault("evaluation", {}).update(seed=2**40), "evaluation.seed")
    add("ev-seed-float", lambda d: d.setdefault("evaluation", {}).update(seed=1.5), "evaluation.seed")
    add("ev-samples-zero", lambda d: d.setdefault("evaluation", {}).update(samples=0), "evaluation.samples")
    add("ev-samples-neg", lambda d: d.setdefault("evaluation", {}).update(samples=-5), "evaluation.samples")
    add("ev-samples-1e20", lambda d: d.setdefault("evaluation", {}).update(samples=10**20), "evaluation.samples")
    add("ev-samples-str", lambda d: d.setdefault("evaluation", {}).update(samples="many"), "evaluation.samples")
    add("ev-samples-bool", lambda d: d.setdefault("evaluation", {}).update(samples=True), "evaluation.samples")
    add("ev-samples-frac", lambda d: d.setdefault("evaluation", {}).update(samples=4096.5), "evaluation.samples")
    add("ev-method", lambda d: d.setdefault("evaluation", {}).update(method="halton"), "evaluation.method")
    add("ev-ranges-empty", lambda d: d.setdefault("evaluation", {}).update(ranges={}), "evaluation.ranges")
    add("ev-ranges-list", lambda d: d.setdefault("evaluation", {}).update(ranges=["x"]), "evaluation.ranges")
    add("ev-ranges-unknown-coord", lambda d: d.setdefault("evaluation", {}).setdefault("ranges", {}).update(
        w=["0 mm", "1 mm"]), "evaluation.ranges.w")
    add("ev-fixed-pose-unknown", lambda d: d.setdefault("evaluation", {}).update(fixed_pose={"w": "0 mm"}),
        "evaluation.fixed_pose.w")
    add("ev-constraints-unknown", lambda d: d.setdefault("evaluation", {}).update(constraints=["nope_constraint"]),
        "evaluation.constraints[0]")
    add("ev-constraints-number", lambda d: d.setdefault("evaluation", {}).update(constraints=[3]),
        "evaluation.constraints")
    add("ev-final-samples-zero", lambda d: d.setdefault("evaluation", {}).update(final_samples=0),
        "evaluation.final_samples")
    add("ev-final-repeats-zero", lambda d: d.setdefault("evaluation", {}).update(final_repeats=0),
        "evaluation.final_repeats")
    add("ev-final-top-neg", lambda d: d.setdefault("evaluation", {}).update(final_top=-1), "evaluation.final_top")
    add("ev-unknown-key", lambda d: d.setdefault("evaluation", {}).update(sample=10), "evaluation.sample")
    if ev.get("ranges"):
        c, (lo, hi) = next(iter(ev["ranges"].items()))
        u = _unit_of(lo)
        add("ev-range-inverted", lambda d: d["evaluation"]["ranges"].update({c: [hi, lo]}), f"evaluation.ranges.{c}")
        add("ev-range-nan", lambda d: d["evaluation"]["ranges"].update({c: [f"nan {u}", hi]}),
            f"evaluation.ranges.{c}[0]")
        add("ev-range-inf", lambda d: d["evaluation"]["ranges"].update({c: [lo, f"inf {u}"]}),
            f"evaluation.ranges.{c}[1]")
        add("ev-range-bare", lambda d: d["evaluation"]["ranges"].update({c: [-1, 1]}), f"evaluation.ranges.{c}[0]")
        add("ev-range-three", lambda d: d["evaluation"]["ranges"].update({c: [lo, hi, hi]}), f"evaluation.ranges.{c}")
        add("ev-fixed-pose-and-range", lambda d: d["evaluation"].update(fixed_pose={c: lo}),
            f"evaluation.fixed_pose.{c}")
    # objectives
    objs = base["objectives"]
    add("obj-unknown", lambda d: d["objectives"][0].update(name="volumee"), "objectives[0].name")
    add("obj-goal", lambda d: d["objectives"][0].update(goal="max"), "objectives[0].goal")
    add("obj-unknown-setting", lambda d: d["objectives"][0].setdefault("settings", {}).update(bogus=1),
        "objectives[0].settings.bogus")
    add("obj-unknown-key", lambda d: d["objectives"][0].update(weight=2), "objectives[0].weight")
    add("obj-label-empty", lambda d: d["objectives"][0].update(label=""), "objectives[0].label")
    for col in pick(RESERVED_COLUMNS, 3):
        add(f"obj-label-{col}", lambda d, col=col: d["objectives"][0].update(label=col), "objectives[0].label")
    if variables:
        add("obj-label-variable", lambda d: d["objectives"][0].update(label=variables[0]["name"]),
            "objectives[0].label")
    if len(objs) >= 2:
        lab = objs[0].get("label", objs[0]["name"])
        add("obj-label-twice", lambda d: d["objectives"][1].update(label=lab), "objectives[1].label")
    from parasynth.measures.objectives import OBJECTIVES

    for j, o in enumerate(objs):
        st = OBJECTIVES[o["name"]].settings
        p = f"objectives[{j}].settings"
        if "quantile" in st:
            for q in pick((5, -0.5, 1.5, "half", True), 2):
                add(f"{p}-quantile-{q}", lambda d, j=j, q=q: d["objectives"][j].setdefault("settings", {}).update(
                    quantile=q), f"{p}.quantile")
        if "n" in st:
            for n in pick((0, -1, 10**20, 2.5, "lots"), 2):
                add(f"{p}-n-{n}", lambda d, j=j, n=n: d["objectives"][j].setdefault("settings", {}).update(n=n),
                    f"{p}.n")
        if "method" in st:
            add(f"{p}-method", lambda d, j=j: d["objectives"][j].setdefault("settings", {}).update(method="halton"),
                f"{p}.method")
        if "ranges" in st:
            add(f"{p}-ranges-coord", lambda d, j=j: d["objectives"][j].setdefault("settings", {}).update(
                ranges={"w": ["0 mm", "1 mm"]}), f"{p}.ranges.w")
        if "constraints" in st:
            add(f"{p}-constraints", lambda d, j=j: d["objectives"][j].setdefault("settings", {}).update(
                constraints=["nope"]), f"{p}.constraints")
        if "seed" in st:
            add(f"{p}-seed", lambda d, j=j: d["objectives"][j].setdefault("settings", {}).update(seed=-3),
                f"{p}.seed")
        for k, kind in st.items():
            if kind == "mass":
                add(f"{p}-{k}-bare", lambda d, j=j, k=k: d["objectives"][j].setdefault("settings", {}).update(
                    {k: 2}), f"{p}.{k}")
                add(f"{p}-{k}-nan", lambda d, j=j, k=k: d["objectives"][j].setdefault("settings", {}).update(
                    {k: "nan kg"}), f"{p}.{k}")
    # robust blocks (the scatter of a robust objective or constraint)
    rob = {"tolerances": {"anchor_tolerance": "0.02 mm"}, "samples": 4}

    def add_rob(cid, change, needle):
        def fn(d):
            r = dict(copy.deepcopy(d["objectives"][0].get("robust") or rob))
            change(r)
            d["objectives"][0]["robust"] = r
        add(cid, fn, needle)

    rp = "objectives[0].robust"
    add_rob("rob-statistic", lambda r: r.update(statistic="median"), f"{rp}.statistic: must be one of mean, quantile, "
                                                                      f"worst, first_order")
    add_rob("rob-quantile-no-level", lambda r: (r.update(statistic="quantile"), r.pop("level", None)), f"{rp}.level")
    add_rob("rob-level-out", lambda r: r.update(statistic="quantile", level=1.5), f"{rp}.level")
    add_rob("rob-level-mean", lambda r: r.update(statistic="mean", level=0.5), f"{rp}.level")
    add_rob("rob-samples-one", lambda r: r.update(samples=1), f"{rp}.samples")
    add_rob("rob-samples-str", lambda r: r.update(samples="many"), f"{rp}.samples")
    add_rob("rob-seed-neg", lambda r: r.update(seed=-1), f"{rp}.seed")
    add_rob("rob-tol-unknown", lambda r: r.update(tolerances={"nope_param": "1 mm"}), f"{rp}.tolerances.nope_param")
    add_rob("rob-tol-bare", lambda r: r.update(tolerances={"anchor_tolerance": 0.01}), f"{rp}.tolerances.anchor_tolerance")
    add_rob("rob-tol-dim", lambda r: r.update(tolerances={"axis_tolerance": "1 mm"}), f"{rp}.tolerances.axis_tolerance")
    add_rob("rob-tol-neg", lambda r: r.update(tolerances={"anchor_tolerance": "-1 mm"}),
            f"{rp}.tolerances.anchor_tolerance")
    add_rob("rob-tol-empty", lambda r: r.update(tolerances={}), f"{rp}.tolerances")
    add_rob("rob-tol-zero", lambda r: r.update(tolerances={"anchor_tolerance": "0 mm"}), f"{rp}.tolerances")
    add_rob("rob-probability-objective", lambda r: r.update(probability=0.9), f"{rp}.probability")
    add_rob("rob-unknown-key", lambda r: r.update(draws=3), f"{rp}.draws")
    # design constraints (added where the study has none)
    k = len(base.get("constraints", []))
    cp = f"constraints[{k}]"

    def add_con(cid, con, needle):
        add(cid, lambda d: d.setdefault("constraints", []).append(con), needle)

    add_con("con-nan-max", {"name": "footprint_radius", "label": "fp", "max": "nan mm"}, f"{cp}.max")
    add_con("con-inf-min", {"name": "footprint_radius", "label": "fp", "min": "-inf mm"}, f"{cp}.min")
    add_con("con-min-above-max", {"name": "footprint_radius", "label": "fp", "min": "300 mm", "max": "100 mm"}, cp)
    add_con("con-no-bound", {"name": "footprint_radius", "label": "fp"}, cp)
    add_con("con-bare", {"name": "footprint_radius", "label": "fp", "max": 150}, f"{cp}.max")
    add_con("con-unknown", {"name": "nope_measure", "max": "1 mm"}, f"{cp}.name")
    add_con("con-label-trial", {"name": "footprint_radius", "label": "trial", "max": "1 m"}, f"{cp}.label")
    add_con("con-label-margin", {"name": "footprint_radius", "label": f"{objs[0].get('label', objs[0]['name'])}_stderr",
                                 "max": "1 m"}, f"{cp}.label")
    add_con("con-dimless-bool", {"name": "home_singularity_margin", "label": "hm", "min": True}, f"{cp}.min")
    add_con("con-dimless-nan", {"name": "home_singularity_margin", "label": "hm", "min": float("nan")}, f"{cp}.min")
    add_con("con-robust-probability", {"name": "home_singularity_margin", "label": "hm", "min": 0.01,
                                       "robust": {"tolerances": {"anchor_tolerance": "0.02 mm"}, "probability": 1.5}},
            f"{cp}.robust.probability")
    add_con("con-robust-two-bounds", {"name": "home_singularity_margin", "label": "hm", "min": 0.01, "max": 0.9,
                                      "robust": {"tolerances": {"anchor_tolerance": "0.02 mm"}, "probability": 0.9}},
            f"{cp}.robust.probability")
    # optimizer
    add("opt-kind", lambda d: d.setdefault("optimizer", {}).update(kind="annealing"), "optimizer.kind")
    add("opt-algorithm", lambda d: d.setdefault("optimizer", {}).update(algorithm="bogus"), "optimizer.algorithm")
    add("opt-seed-neg", lambda d: d.setdefault("optimizer", {}).update(seed=-1), "optimizer.seed")
    add("opt-n-jobs-zero", lambda d: d.setdefault("optimizer", {}).update(n_jobs=0), "optimizer.n_jobs")
    if base.get("optimizer", {}).get("kind") == "optuna":
        add("optuna-n-trials-zero", lambda d: d["optimizer"].update(n_trials=0), "optimizer.n_trials")
        add("optuna-n-trials-neg", lambda d: d["optimizer"].update(n_trials=-3), "optimizer.n_trials")
        if "structure" not in base:  # a study over structures always has its structure variable
            add("optuna-no-variables", lambda d: (d.update(variables=[]), d.pop("reference", None)), "variables")
        add("optuna-population-one", lambda d: d["optimizer"].update(population_size=1), "optimizer.population_size")
    if base.get("optimizer", {}).get("kind") == "nlopt":
        add("nlopt-maxeval-zero", lambda d: d["optimizer"].update(maxeval=0), "optimizer.maxeval")
        add("nlopt-no-variables", lambda d: (d.update(variables=[]), d.pop("reference", None)), "variables")
        add("nlopt-xtol-neg", lambda d: d["optimizer"].update(xtol_rel=-1.0), "optimizer.xtol_rel")
        add("nlopt-start-unknown", lambda d: d["optimizer"].update(start={"nope": "1 mm"}), "optimizer.start.nope")
        v0 = variables[0]
        add("nlopt-start-outside", lambda d: d["optimizer"].update(start={v0["name"]: "9 m"}),
            f"optimizer.start.{v0['name']}")
    # reference and fixed: non-positive lengths and unknown parameters
    ref = base.get("reference") or {}
    ref_len = [p for p in ref if kinds.get(p) == "length" and p in ("link_length", "slider_radius", "a1", "b1",
                                                                    "platform_radius", "base_radius")]
    for p_ in ref_len[:2]:
        add(f"ref-{p_}-zero", lambda d, p_=p_: d["reference"].update({p_: "0 mm"}), f"reference.{p_}")
        add(f"ref-{p_}-neg", lambda d, p_=p_: d["reference"].update({p_: "-5 mm"}), f"reference.{p_}")
    if ref:
        add("ref-unknown", lambda d: d["reference"].update(nope_param="1 mm"), "reference.nope_param")
    add("fixed-unknown", lambda d: d.setdefault("fixed", {}).update(nope_param="1 mm"), "fixed.nope_param")
    names = {v["name"] for v in variables} | set(base.get("fixed", {})) | set(base.get("tied", {}))
    free_len = [p for p, kd in kinds.items() if kd == "length" and p not in names and p in (
        "link_length", "slider_radius", "link_diameter", "platform_radius", "base_radius")]
    for p_ in free_len[:1]:
        add(f"fixed-{p_}-neg", lambda d, p_=p_: d.setdefault("fixed", {}).update({p_: "-1 mm"}), f"fixed.{p_}")
        add(f"fixed-{p_}-zero", lambda d, p_=p_: d.setdefault("fixed", {}).update({p_: "0 mm"}), f"fixed.{p_}")
    add("tied-unknown", lambda d: d.update(tied={"nope_param": "x"}), "tied.nope_param")
    # text-level: duplicate keys, alias bomb, deep nesting, encoding
    add_text("dup-top-name", text0 + "\nname: again\n", "duplicate key 'name'")
    lines = text0.splitlines()
    i_ev = next((j for j, ln in enumerate(lines) if ln.startswith("evaluation:") and ln.strip() == "evaluation:"), None)
    if i_ev is not None:
        dup = lines[: i_ev + 1] + ["  seed: 1", "  seed: 2"] + lines[i_ev + 1:]
        add_text("dup-evaluation-seed", "\n".join(dup) + "\n", "duplicate key 'seed'")
    bomb = "\n".join(["x0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]"] + [
        f"x{j}: &a{j} [" + ", ".join([f"*a{j - 1}"] * 10) + "]" for j in range(1, 9)])
    add_text("alias-bomb", text0 + "\n" + bomb + "\n", "aliases")
    add_text("deep-nesting", text0 + "\nextra: " + "[" * 3000 + "]" * 3000 + "\n", "nested deeper")
    # Every other case, alternating between studies: each kind of mutation is still applied to
    # about half of the studies, and the corpus stays fast.
    return [c for j, c in enumerate(out) if (j + si) % 2 == 0]


STUDY_CASES = [c for si, f in enumerate(STUDY_FILES) for c in _study_mutations(f, si)]


@pytest.mark.parametrize("cid,text,needle", STUDY_CASES, ids=[c[0] for c in STUDY_CASES])
def test_study_mutation_is_refused_by_validate(tmp_path, cid, text, needle):
    src = next(f for f in STUDY_FILES if f.stem == cid.split(":")[0])
    p = tmp_path / src.name  # same folder semantics for relative mechanism paths do not matter here
    p.write_text(text)
    code, out, err = run_cli(["validate", p])
    assert_refused(code, err, needle)
    assert code == 2


def test_corpus_size():
    n = len(STUDY_CASES) + len(DESC_CASES) + len(CLI_CASES) + len(API_PARAM_CASES) + len(API_POSE_CASES)
    assert len(STUDY_CASES) >= 300
    assert n >= 600


def test_shipped_studies_validate():
    """The unmutated files are accepted: the corpus refuses the mutation, not the file."""
    for f in STUDY_FILES:
        code, out, err = run_cli(["validate", f])
        assert code == 0, err
        assert "valid study" in out


@pytest.mark.parametrize("f", STUDY_FILES, ids=[f.stem for f in STUDY_FILES])
def test_documented_acceptance_sweep_without_variables(tmp_path, f):
    """A sweep with no design variables is accepted (it evaluates the reference only)."""
    d = _load(f)
    d["variables"] = []
    d["optimizer"] = {"kind": "sweep"}
    d.pop("tied", None)
    for k in ("screening", "eta", "keep"):  # successive halving: refused in a sweep (docs/structures.md)
        d.get("structure", {}).pop(k, None)
    p = tmp_path / "s.yaml"
    p.write_text(yaml.safe_dump(d, sort_keys=False))
    code, out, err = run_cli(["validate", p])
    assert code == 0, err


# -- validate refuses what run rejects ----------------------------------------------------------
RUN_REJECTS = [
    # (mutation of quickstart, needle): each makes every design fail (or the run misbehave) at run time
    (lambda d: d["reference"].update(link_length="0 mm"), "reference.link_length"),
    (lambda d: d["variables"][0].update(low="-20 mm"), "variables[0].low"),
    (lambda d: d.setdefault("fixed", {}).update(link_diameter="-8 mm"), "fixed.link_diameter"),
    (lambda d: d["evaluation"]["ranges"].update(w=["0 mm", "1 mm"]), "evaluation.ranges.w"),
    (lambda d: d["evaluation"].update(constraints=["stroke", "nope"]), "evaluation.constraints[1]"),
    (lambda d: d["objectives"][1]["settings"].update(quantile=5), "objectives[1].settings.quantile"),
    (lambda d: d["constraints"][0].update(max="nan mm"), "constraints[0].max"),
    (lambda d: d["objectives"][0].setdefault("settings", {}).update(fixed={"w": "0 mm"}), "objectives[0].settings.fixed.w"),
]


@pytest.mark.parametrize("k", range(len(RUN_REJECTS)))
def test_validate_and_run_refuse_before_evaluating(tmp_path, k):
    mutate, needle = RUN_REJECTS[k]
    d = _load(ROOT / "studies" / "quickstart.yaml")
    d["evaluation"].update(samples=64)
    d["evaluation"].pop("final_samples", None)
    d["optimizer"].update(n_trials=2, population_size=2)
    mutate(d)
    p = tmp_path / "s.yaml"
    p.write_text(yaml.safe_dump(d, sort_keys=False))
    code, _, err = run_cli(["validate", p])
    assert_refused(code, err, needle)
    code, _, err = run_cli(["run", p, "--out", tmp_path / "run", "--quiet", "--no-report"])
    assert_refused(code, err, needle)
    assert not (tmp_path / "run" / "results.csv").exists()


# -- mechanism descriptions ---------------------------------------------------------------------
def _desc_mutations(path):
    text0 = path.read_text()
    base = yaml.safe_load(text0)
    out = []

    def add(cid, fn, needle):
        d = copy.deepcopy(base)
        if fn(d) is False:
            return
        out.append((f"{path.stem}:{cid}", yaml.safe_dump(d, sort_keys=False), needle))

    params = base.get("parameters") or {}
    def _val(v):
        return v.get("value") if isinstance(v, dict) else v

    lengths = [k for k, v in params.items() if isinstance(_val(v), str) and _val(v).endswith(" mm")
               and float(_val(v).split()[0]) != 0]
    for k in lengths[:3]:
        add(f"param-{k}-bare", lambda d, k=k: d["parameters"].update({k: 300}), f"parameters.{k}")
        add(f"param-{k}-nan", lambda d, k=k: d["parameters"].update({k: "nan mm"}), f"parameters.{k}")
        add(f"param-{k}-bool", lambda d, k=k: d["parameters"].update({k: True}), f"parameters.{k}")
        add(f"param-{k}-dim", lambda d, k=k: d["parameters"].update({k: "3 kg"}), f"parameters.{k}")
    add("unknown-top-key", lambda d: d.update(legz=[]), "legz")
    add("params-list", lambda d: d.update(parameters=[1, 2]), "parameters")
    for side in ("base", "platform"):
        for name, a in (base.get(side) or {}).items():
            if isinstance(a, dict) and a.get("pattern") == "polygon":
                p = f"{side}.{name}.n"
                add(f"{side}-{name}-n-huge", lambda d, side=side, name=name: d[side][name].update(n=200_000), p)
                add(f"{side}-{name}-n-zero", lambda d, side=side, name=name: d[side][name].update(n=0), p)
                add(f"{side}-{name}-n-bool", lambda d, side=side, name=name: d[side][name].update(n=True), p)
                add(f"{side}-{name}-n-float", lambda d, side=side, name=name: d[side][name].update(n=3.5), p)
    out.append((f"{path.stem}:dup-name", text0 + "\nname: again\n", "duplicate key 'name'"))
    bomb = "\n".join(["x0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]"] + [
        f"x{j}: &a{j} [" + ", ".join([f"*a{j - 1}"] * 10) + "]" for j in range(1, 9)])
    out.append((f"{path.stem}:alias-bomb", text0 + "\n" + bomb + "\n", "aliases"))
    out.append((f"{path.stem}:deep", text0 + "\nextra: " + "[" * 3000 + "]" * 3000 + "\n", "nested deeper"))
    out.append((f"{path.stem}:binary", "\x00\x01\x02", "binary"))
    return out


DESC_CASES = [c for f in DESC_FILES for c in _desc_mutations(f)]


@pytest.mark.parametrize("cid,text,needle", DESC_CASES, ids=[c[0] for c in DESC_CASES])
def test_description_mutation_is_refused(tmp_path, cid, text, needle):
    p = tmp_path / (cid.split(":")[0] + "_mutated.yaml")
    p.write_text(text)
    code, out, err = run_cli(["analyze", p, "--samples", "1"])
    assert_refused(code, err, needle)
    assert code == 2


# -- command-line arguments ---------------------------------------------------------------------
Q = str(ROOT / "studies" / "quickstart.yaml")
CLI_CASES = [
    (["run", Q, "--n-trials", "0"], "--n-trials"),
    (["run", Q, "--n-trials", "-3"], "--n-trials"),
    (["run", Q, "--n-trials", "three"], "--n-trials"),
    (["run", Q, "--n-trials", "2.5"], "--n-trials"),
    (["run", Q, "--n-trials", "99999999999"], "--n-trials"),
    (["run", Q, "--out", ""], "--out"),
    (["run", Q, "--report-dir", ""], "--report-dir"),
    (["run", ""], "study"),
    (["run"], "study"),
    (["run", Q, "--bogus"], "--bogus"),
    (["validate"], "study"),
    (["validate", Q, Q], "unrecognized"),
    (["evaluate", Q, "--samples", "-1"], "--samples"),
    (["evaluate", Q, "--samples", "0"], "--samples"),
    (["evaluate", Q, "--samples", "10^13"], "--samples"),
    (["evaluate", Q, "--samples", "10000000000000"], "--samples"),
    (["evaluate", Q, "--samples", "1e20"], "--samples"),
    (["evaluate", Q, "--set", "link_length"], "--set"),
    (["evaluate", Q, "--set", "nope=1 mm"], "--set nope"),
    (["evaluate", Q, "--set", "link_length=200"], "--set link_length"),
    (["evaluate", Q, "--set", "link_length=inf mm"], "--set link_length"),
    (["evaluate", Q, "--set", "link_length=2 kg"], "--set link_length"),
    (["evaluate", Q, "--set", "link_length=-5 mm"], "link_length"),
    (["analyze", "nope"], "nope"),
    (["analyze", "5pus_upu", "--param", "link_length"], "--param"),
    (["analyze", "5pus_upu", "--param", "link_length=205"], "--param link_length"),
    (["analyze", "5pus_upu", "--param", "link_length=-205 mm"], "link_length"),
    (["analyze", "5pus_upu", "--param", "link_length=true"], "link_length"),
    (["analyze", "5pus_upu", "--param", "nope=1"], "nope"),
    (["analyze", "5pus_upu", "--samples", "-1"], "--samples"),
    (["analyze", "5pus_upu", "--samples", "10000000000000"], "--samples"),
    (["analyze", "5pus_upu", "--seed", "-1"], "--seed"),
    (["analyze", "missing_file.yaml"], "missing_file.yaml"),
    (["report", "/no/such/run/dir"], "/no/such/run/dir"),
    (["report", Q], "is a file"),
    (["run-all", "/no/such/folder"], "/no/such/folder"),
    (["run-all", Q], "is a file"),
    (["schema", "--out", str(ROOT / "studies")], "is a directory"),
    (["bogus-command"], "bogus-command"),
    ([], "COMMAND"),
]


@pytest.mark.parametrize("args,needle", CLI_CASES, ids=[" ".join(a)[-60:] or "(none)" for a, _ in CLI_CASES])
def test_cli_argument_is_refused(args, needle):
    code, out, err = run_cli(args)
    assert_refused(code, err, needle)


def test_validate_into_a_closed_pipe():
    """``parasynth validate ... | head -2`` when the reader has gone: the pipe's read end is
    closed before the command writes, so its first write fails. No traceback, one line, 141."""
    import os
    import subprocess
    import sys

    r, w = os.pipe()
    os.close(r)
    try:
        p = subprocess.run([sys.executable, "-m", "parasynth.cli", "validate", Q], stdout=w,
                           stderr=subprocess.PIPE, timeout=300)
    finally:
        os.close(w)
    err = p.stderr.decode()
    assert "Traceback" not in err, err
    assert p.returncode == 141, (p.returncode, err)
    assert err.count("\n") == 1 and "broken pipe" in err


# -- Python API: parameters ---------------------------------------------------------------------
def _api_param_cases():
    from parasynth.mechanisms import list_mechanisms, mechanism_class

    out = []
    for name in list_mechanisms():
        cls = mechanism_class(name)
        units = getattr(cls.Params, "UNITS", {})
        defaults = cls.Params()
        for f in dataclasses.fields(defaults):
            kind = units.get(f.name)
            if kind not in ("length", "angle", "dimensionless"):
                continue
            v0 = getattr(defaults, f.name)
            if isinstance(v0, (int, float)) and not isinstance(v0, bool):
                bad = [True, False, "0.2", 0.2 + 0j, None, float("nan"), float("inf"), -float("inf"), [0.2]]
            else:
                a = np.asarray(v0, dtype=float)
                bad = ["abc", True, np.full(a.shape, np.nan).tolist(), (a + 0j).tolist(), np.zeros(a.shape + (2,)).tolist()]
            for b in bad:
                out.append((name, f.name, b))
    # declared physical ranges
    out += [("5pus_upu", "link_length", -0.1), ("5pus_upu", "link_length", 0.0), ("3rps", "sphere_max", -0.1),
            ("3rps", "base_radius", -0.3), ("3prs", "platform_radius", -0.1), ("gough_stewart_6ups", "base_radius", 0.0),
            ("2rpu_2sps", "a1", -0.15), ("4ups_1rps", "platform_radius", -0.1)]
    return out


API_PARAM_CASES = _api_param_cases()


@pytest.mark.parametrize("name,field,value", API_PARAM_CASES,
                         ids=[f"{n}.{f}={v!r}"[:60] for n, f, v in API_PARAM_CASES])
def test_api_parameter_is_refused_naming_the_field(name, field, value):
    with pytest.raises(ValueError) as e:
        parasynth.load_mechanism(name, **{field: value})
    assert field in str(e.value)


# -- Python API: poses --------------------------------------------------------------------------
def _api_pose_cases():
    from parasynth.mechanisms import list_mechanisms

    out = []
    for name in list_mechanisms():
        for what in ("str", "complex", "bool", "none", "str-in-list", "bytes"):
            out.append((name, what))
    return out


API_POSE_CASES = _api_pose_cases()


def _bad_pose(mech, what):
    home = np.asarray(mech.home, dtype=float)
    return {
        "str": np.array([str(x) for x in home]),
        "complex": home + 0j,
        "bool": np.ones(mech.n_task, dtype=bool),
        "none": None,
        "str-in-list": ["0.1"] + home[1:].tolist(),
        "bytes": b"\x00" * mech.n_task,
    }[what]


@pytest.mark.parametrize("name,what", API_POSE_CASES, ids=[f"{n}-{w}" for n, w in API_POSE_CASES])
def test_api_pose_of_wrong_type_is_refused(name, what):
    mech = parasynth.load_mechanism(name)
    X = _bad_pose(mech, what)
    for method in (mech.inverse_kinematics, mech.jacobian, mech.singularity_margin, mech.is_feasible,
                   mech.constraint_margins):
        with pytest.raises(ValueError) as e:
            method(X)
        assert re.search(r"pose|X\b", str(e.value)), str(e.value)


@pytest.mark.parametrize("name", parasynth.list_mechanisms())
@pytest.mark.parametrize("big", [1e308, -1e308, 1e200, 1e7])
def test_api_huge_pose_is_masked(name, big):
    mech = parasynth.load_mechanism(name)
    assert mech.task_coordinates[0] not in mech.angular_coordinates  # a position coordinate
    X = np.array([mech.home, mech.home])
    X[1, 0] = big
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ik = mech.inverse_kinematics(X)
        s = mech.singularity_margin(X)
        feas = mech.is_feasible(X)
        margins = mech.constraint_margins(X)
    assert ik.reachable.tolist() == [True, False]
    assert np.all(np.isnan(ik.actuators[1])) and np.all(np.isfinite(ik.actuators[0]))
    assert np.isfinite(s[0]) and not feas[1]
    for k, m in margins.items():
        assert m[1] == -math.inf, k


# -- Python API: sample counts ------------------------------------------------------------------
API_COUNT_CASES = [1e20, 10**13, 2**22 + 1, 0, -1, 2.5, True, "100", None, float("nan")]


@pytest.mark.parametrize("n", API_COUNT_CASES, ids=[repr(n) for n in API_COUNT_CASES])
def test_api_sample_count_is_refused_up_front(n):
    import time

    from parasynth.measures.objectives import get, workspace_of

    mech = parasynth.load_mechanism("5pus_upu")
    t0 = time.perf_counter()
    with pytest.raises(ValueError) as e:
        workspace_of(mech, n=n)
    assert re.search(r"\bn\b", str(e.value)), str(e.value)
    with pytest.raises(ValueError):
        get("workspace_volume")(mech, n=n)
    assert time.perf_counter() - t0 < 5.0


@pytest.mark.parametrize("name", parasynth.list_mechanisms())
@pytest.mark.parametrize("what", ["str", "complex", "bool"])
def test_api_actuators_of_wrong_type_are_refused(name, what):
    mech = parasynth.load_mechanism(name)
    q = np.asarray(mech.inverse_kinematics(mech.home).actuators, dtype=float)
    bad = {"str": np.array([str(x) for x in q]), "complex": q + 0j, "bool": np.ones(q.shape, dtype=bool)}[what]
    fixed = {"gamma": 0.0} if name == "4ups_1rps" else None
    with pytest.raises(ValueError) as e:
        mech.forward_kinematics(bad, fixed=fixed)
    assert "actuator" in str(e.value)


# -- options that would be silently ignored ---------------------------------------------------
IGNORED_OPTION_CASES = [
    (["run", Q, "--resume", "--out", "{tmp}/no_such_run", "--quiet", "--n-trials", "1", "--no-report"],
     "does not exist"),
    (["report", "{tmp}", "--run-dir", "{tmp}/elsewhere"], "--run-dir"),
    (["run", Q, "--no-report", "--report-dir", "{tmp}/rep", "--quiet"], "--report-dir"),
    (["run", Q, "--storage", "optuna.db", "--out", "{tmp}/r", "--quiet", "--n-trials", "1", "--no-report"],
     "journal:optuna.db"),
]


@pytest.mark.parametrize("args,needle", IGNORED_OPTION_CASES, ids=["resume-missing-dir", "report-run-dir",
                                                                  "report-dir-no-report", "bare-storage"])
def test_an_option_acts_or_is_refused(tmp_path, args, needle):
    code, out, err = run_cli([a.replace("{tmp}", str(tmp_path)) for a in args])
    assert_refused(code, err, needle)
    assert len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "no_such_run").exists() and not (tmp_path / "r" / "journal.jsonl").exists()


def test_optimizer_storage_that_is_no_url_is_refused():
    d = _load(ROOT / "studies" / "quickstart.yaml")
    d["optimizer"]["storage"] = "optuna.db"
    with pytest.raises(parasynth.study.StudyError, match=r"optimizer\.storage"):
        parasynth.study.load_study(yaml.safe_dump(d), is_text=True)


# -- damaged run directories -------------------------------------------------------------------
def _tiny_run(tmp_path):
    from parasynth.study import load_study, run_study

    d = _load(ROOT / "studies" / "quickstart.yaml")
    d["evaluation"].update(samples=64, final_samples=64, final_repeats=2, final_top=1)
    d["optimizer"].update(n_trials=2, population_size=2)
    run_study(load_study(yaml.safe_dump(d), is_text=True), out_dir=tmp_path / "run", progress=False)
    return tmp_path / "run"


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    return _tiny_run(tmp_path_factory.mktemp("tiny"))


JOURNAL_NOT_RECORDS = [("list", "[1, 2]"), ("number", "3.5"), ("string", '"trial"'), ("null", "null"),
                       ("object-without-values", '{"trial": 7, "source": "run"}'),
                       ("values-not-a-mapping", '{"trial": 7, "values": [1, 2]}'),
                       ("unknown-source", '{"trial": 7, "source": "elsewhere", "values": {}}')]


@pytest.mark.parametrize("where", ["last", "middle"])
@pytest.mark.parametrize("cid,line", JOURNAL_NOT_RECORDS, ids=[c for c, _ in JOURNAL_NOT_RECORDS])
def test_report_of_a_journal_line_that_is_not_a_record(tiny_run, tmp_path, cid, line, where):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    j = run / "journal.jsonl"
    lines = j.read_text().splitlines()
    k = len(lines) if where == "last" else 1
    lines.insert(k, line)
    j.write_text("\n".join(lines) + "\n")
    code, out, err = run_cli(["report", run, "--out", tmp_path / "rep"])
    assert_refused(code, err, "journal.jsonl", f"line {k + 1}")
    assert len(err.strip().splitlines()) == 1, err


FINAL_GARBAGE = [("binary", b"\xff\xfe\x00garbage,\n1,2,3\n4", "final.csv"),
                 ("no-columns", b"a,b\n1,2\n", "line 1"),
                 ("text-value", None, "line 3"),
                 ("bad-source", None, "line 2"),
                 ("empty", b"", "empty"),
                 ("ragged", b"source,volume\nbest,1\nbest,1,2,3,4\n", "final.csv")]


@pytest.mark.parametrize("cid,content,needle", FINAL_GARBAGE, ids=[c for c, _, _ in FINAL_GARBAGE])
def test_report_of_a_garbage_final_csv(tiny_run, tmp_path, cid, content, needle):
    import shutil

    import pandas as pd

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    f = run / "final.csv"
    if content is None:
        df = pd.read_csv(f)
        assert len(df) >= 2
        if cid == "text-value":
            df["volume_m3"] = df["volume_m3"].astype(object)  # final.csv names its units
            df.loc[1, "volume_m3"] = "lots"
        else:
            df.loc[0, "source"] = "somewhere"
        df.to_csv(f, index=False)
    else:
        f.write_bytes(content)
    code, out, err = run_cli(["report", run, "--out", tmp_path / "rep"])
    assert_refused(code, err, "final.csv", needle)
    assert len(err.strip().splitlines()) == 1, err


# -- absurd values, wrong types in the Python API ----------------------------------------------
@pytest.mark.parametrize("name", parasynth.list_mechanisms())
@pytest.mark.parametrize("big", [1e300, -1e300, 1e7])
def test_absurd_parameter_value_is_a_clear_error(name, big):
    from parasynth.mechanisms import mechanism_class

    P = mechanism_class(name).Params
    units = getattr(P, "UNITS", {})
    for f in dataclasses.fields(P()):
        if units.get(f.name) not in ("length", "angle") or not isinstance(getattr(P(), f.name), float):
            continue
        with pytest.raises(ValueError, match=re.escape(f.name)):
            parasynth.load_mechanism(name, **{f.name: big})


def test_absurd_parameter_on_the_command_line():
    code, out, err = run_cli(["analyze", "5pus_upu", "--param", "link_length=1e300 mm"])
    assert_refused(code, err, "link_length", "at most")
    assert code == 2 and "OverflowError" not in err


API_TYPE_CASES = [
    ("workspace-mech-str", lambda m: parasynth.workspace("5pus_upu", {"x": (-0.1, 0.1)}), "mech"),
    ("workspace-mech-none", lambda m: parasynth.workspace(None, {"x": (-0.1, 0.1)}), "mech"),
    ("measure-mech-str", lambda m: parasynth.objectives.get("workspace_volume")("5pus_upu"), "mech"),
    ("measure-mech-number", lambda m: parasynth.objectives.get("footprint_radius")(3.0), "mech"),
    ("workspace-constraints-number", lambda m: parasynth.workspace(m, {"x": (-0.1, 0.1)}, constraints=5),
     "constraints"),
    ("measure-constraints-number", lambda m: parasynth.objectives.get("workspace_volume")(m, constraints=2.5),
     "constraints"),
    ("is_feasible-names-number", lambda m: m.is_feasible(m.home, names=5), "names"),
    ("margins-names-dict", lambda m: m.constraint_margins(m.home, names={"stroke": 1}), "names"),
]


@pytest.mark.parametrize("cid,call,arg", API_TYPE_CASES, ids=[c for c, _, _ in API_TYPE_CASES])
def test_api_argument_of_wrong_type_is_a_type_error(cid, call, arg):
    import parasynth.measures.objectives  # noqa: F401

    mech = parasynth.load_mechanism("5pus_upu")
    with pytest.raises(TypeError) as e:
        call(mech)
    assert str(e.value).startswith(f"{arg} must be"), str(e.value)


# -- degenerate geometry -----------------------------------------------------------------------
def _degenerate_description(tmp_path) -> Path:
    text = (ROOT / "src" / "parasynth" / "mechanisms" / "gough_stewart_6ups.yaml").read_text()
    text = text.replace("name: gough_stewart_6ups", "name: coincident_6ups")
    text = re.sub(r"  A: \{pattern: paired.*\}", "  A: {pattern: polygon, n: 6, radius: 0 mm, phase: 0 deg}", text)
    text = text.replace('platform: "A[5, 0, 1, 2, 3, 4]"', "platform: A")
    p = tmp_path / "coincident.yaml"
    p.write_text(text)
    return p


def test_validate_refuses_coincident_anchors_and_a_mechanism_singular_everywhere(tmp_path):
    desc = _degenerate_description(tmp_path)
    study = {"name": "degenerate", "mechanism": desc.name,
             "variables": [{"name": "base_radius", "low": "400 mm", "high": "600 mm"}],
             "objectives": [{"name": "workspace_volume", "goal": "maximize"}],
             "evaluation": {"samples": 256, "ranges": {"x": ["-100 mm", "100 mm"], "y": ["-100 mm", "100 mm"],
                                                       "z": ["400 mm", "800 mm"]}},
             "optimizer": {"kind": "optuna", "n_trials": 4}}
    p = tmp_path / "degenerate.yaml"
    p.write_text(yaml.safe_dump(study))
    code, out, err = run_cli(["validate", p])
    assert_refused(code, err, "degenerate geometry: the 6 platform anchors coincide", "singular at its home pose")
    assert code == 2
    # the shipped classic is not degenerate
    ok = dict(study, mechanism="gough_stewart_6ups")
    p.write_text(yaml.safe_dump(ok))
    code, out, err = run_cli(["validate", "--quick", p])
    assert code == 0, err


def test_analyze_reports_a_singular_home_as_a_finding(tmp_path):
    desc = _degenerate_description(tmp_path)
    code, out, err = run_cli(["analyze", desc, "--samples", "50"])
    assert code == 0 and "internal error" not in err and "Traceback" not in err, err
    findings = out.split("findings:")[1]
    assert "the home pose is singular" in findings
    assert "the pose limit interference is violated at home" in findings
    assert "the 6 platform anchors coincide" in findings
    # parameters in display units, angles in degrees
    assert "base_separation = 20 deg" in out and "base_radius = 500 mm" in out
    code, out, err = run_cli(["analyze", "5pus_upu", "--samples", "50"])
    assert code == 0 and "findings:" not in out, out
