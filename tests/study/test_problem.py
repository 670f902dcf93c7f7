"""The problem object and the runners against it: the differential-evolution runner of
docs/architecture.md ("Adding a runner", the code of docs/runner_example.py) finds the known
optimum of an analytic problem and improves on the centre of a real study."""

import importlib.util
import re
from pathlib import Path

import pytest

from parasynth.study import load_study
from parasynth.study.evaluate import Record
from parasynth.study.problem import Problem, RunContext
from parasynth.study.optimizers import BaseOptimizer, registered

DOCS = Path(__file__).resolve().parents[2] / "docs"

STUDY = """
name: de_test
mechanism: 5pus_upu
variables:
  - {name: link_length, low: 160 mm, high: 240 mm}
  - {name: slider_radius, low: 110 mm, high: 170 mm}
objectives: [{name: workspace_volume, label: volume, goal: maximize}]
evaluation:
  samples: 512
  seed: 0
  ranges: {x: [-200 mm, 200 mm], y: [-200 mm, 200 mm], z: [-450 mm, 300 mm]}
optimizer: {kind: nlopt, seed: 3}
"""


def _example():
    spec = importlib.util.spec_from_file_location("runner_example", DOCS / "runner_example.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_documented_runner_is_the_tested_file():
    doc = (DOCS / "architecture.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", doc, flags=re.S)
    code = (DOCS / "runner_example.py").read_text()
    assert code in blocks


def test_registry_names_every_kind():
    reg = registered()
    assert {"sweep", "nlopt", "optuna"} <= set(reg)
    assert all(issubclass(c, BaseOptimizer) and c.kind == k for k, c in reg.items())


class Analytic(Problem):
    """The study's space with an analytic objective: maximum 1 at (0.21 m, 0.125 m)."""

    calls = 0

    def evaluate(self, values, trial=-1, source="run", n=None, seed=None):
        self.calls += 1
        f = 1.0 - ((values["link_length"] - 0.21) / 0.08) ** 2 - ((values["slider_radius"] - 0.125) / 0.06) ** 2
        return Record(values=dict(values), objectives={"volume": f}, trial=trial, source=source)


def test_de_runner_finds_the_optimum_of_an_analytic_problem():
    problem = Analytic(load_study(STUDY, is_text=True))
    records = []
    _example().run_de(problem, RunContext(records, records.append, n_trials=400))
    assert 0 < len(records) <= 400 and problem.calls == len(records)
    assert [r.trial for r in records] == list(range(len(records)))
    best = max(records, key=lambda r: r.objectives["volume"])
    assert best.values["link_length"] == pytest.approx(0.21, abs=2e-3)
    assert best.values["slider_radius"] == pytest.approx(0.125, abs=2e-3)
    assert best.objectives["volume"] > 0.999


def test_de_runner_resumes_without_repeating_designs():
    problem = Analytic(load_study(STUDY, is_text=True))
    first = []
    _example().run_de(problem, RunContext(first, first.append, n_trials=40))
    assert len(first) == 40
    again = list(first)
    problem.calls = 0
    _example().run_de(problem, RunContext(again, again.append, n_trials=60))
    # the resumed run replays the same seeded path: the first 40 designs come from the records
    assert problem.calls == 20 and len(again) == 60 and [r.trial for r in again] == list(range(60))


def test_de_runner_improves_on_the_centre_of_a_real_study():
    problem = Problem(load_study(STUDY, is_text=True))
    centre = problem.evaluate(problem.space.centre())
    assert centre.status == "ok"
    records = []
    _example().run_de(problem, RunContext(records, records.append, n_trials=24), popsize=6)
    assert len(records) == 24 and all(r.status == "ok" for r in records)
    best = max(r.objectives["volume"] for r in records)
    assert best > centre.objectives["volume"]


SHARED = """
name: shared_measure
mechanism: 5pus_upu
variables:
  - {name: link_length, low: 160 mm, high: 240 mm}
objectives:
  - {name: singularity_margin_min, label: margin_q05, goal: maximize, settings: {quantile: 0.05}}
  - {name: singularity_margin_min, label: margin_q10, goal: maximize, settings: {quantile: 0.10}}
constraints:
  - {name: singularity_margin_min, label: margin_min, min: 0.001, settings: {quantile: 0.05}}
  - {name: singularity_margin_min, label: margin_small, min: 0.001, settings: {quantile: 0.05, n: 256}}
evaluation:
  samples: 512
  seed: 0
  ranges: {x: [-200 mm, 200 mm], y: [-200 mm, 200 mm], z: [-450 mm, 300 mm]}
optimizer: {kind: optuna, n_trials: 4, seed: 3}
"""


def test_a_measure_asked_twice_with_the_same_arguments_is_computed_once(tmp_path, monkeypatch):
    """A constraint and an objective of the same measure and settings share one computation;
    other settings (a quantile, a sample size) are computed apart; and every value is the one
    the measure gives alone."""
    from parasynth.measures import objectives as obj
    from parasynth.study.evaluate import Evaluator

    f = tmp_path / "s.yaml"
    f.write_text(SHARED)
    problem = Problem(load_study(f))
    values = {"link_length": 0.2}
    m = obj.get("singularity_margin_min")
    calls = []
    value = Evaluator._value

    def counted(item, mech, args, rec, bound=None, probability=None):
        calls.append(item.label)
        return value(item, mech, args, rec, bound=bound, probability=probability)

    monkeypatch.setattr(Evaluator, "_value", staticmethod(counted))
    rec = problem.evaluate(values)
    assert rec.status == "ok", rec.error
    # margin_min and margin_q05 once; margin_q10 (another quantile) and margin_small (another sample) apart
    assert sorted(calls) == ["margin_min", "margin_q10", "margin_small"]
    assert rec.objectives["margin_q05"] == rec.constraint_values["margin_min"]
    monkeypatch.setattr(Evaluator, "_value", staticmethod(value))
    mech = problem.evaluator.build(values)
    sample = problem.evaluator.sample()
    alone = m(mech, sample=sample, quantile=0.05)
    assert rec.objectives["margin_q05"] == alone
    assert rec.objectives["margin_q10"] == m(mech, sample=sample, quantile=0.10)
    assert rec.objectives["margin_q10"] > rec.objectives["margin_q05"]


def test_kept_arguments_give_what_fresh_ones_give(tmp_path):
    """The evaluator keeps a sample and the measures' arguments per (n, seed): a second design,
    and a re-evaluation with its own sample size and seed, get the values a new evaluator
    (nothing kept) and the measures called alone give."""
    from parasynth.measures import objectives as obj
    from parasynth.study.evaluate import Evaluator

    f = tmp_path / "s.yaml"
    f.write_text(SHARED)
    study = load_study(f)
    ev = Evaluator(study)
    first = ev.evaluate({"link_length": 0.2})
    second = ev.evaluate({"link_length": 0.21})
    again = ev.evaluate({"link_length": 0.21}, n=256, seed=5)
    other = ev.evaluate({"link_length": 0.21}, n=256, seed=6)
    assert ev.sample() is ev.sample() and ev.sample(256, 5) is not ev.sample()
    assert ev.sample(256, 5).n == 256 and ev.sample(256, 5).seed == 5
    for rec, kw in ((second, {}), (again, {"n": 256, "seed": 5}), (other, {"n": 256, "seed": 6})):
        fresh = Evaluator(study).evaluate({"link_length": 0.21}, **kw)
        assert rec.status == fresh.status == "ok", rec.error
        assert rec.objectives == fresh.objectives and rec.constraint_values == fresh.constraint_values
    assert first.objectives != second.objectives and other.objectives != again.objectives
    mech = ev.build({"link_length": 0.21})
    alone = obj.get("singularity_margin_min")(mech, sample=ev.sample(256, 5), quantile=0.05)
    assert again.objectives["margin_q05"] == alone != second.objectives["margin_q05"]


def test_a_run_builds_every_design_from_the_class_it_resolved_first(tmp_path):
    """The model class of a study is resolved once per study object: a description file edited
    during a run does not change the model of the designs that follow (a new study of the file
    takes the new class); bad design parameters are still refused by name."""
    import shutil

    import os

    import parasynth
    from parasynth.study.design import design_mechanism, study_class

    src = Path(parasynth.__file__).parent / "mechanisms" / "5pus_upu.yaml"
    desc = tmp_path / "m.yaml"
    shutil.copy(src, desc)
    f = tmp_path / "s.yaml"
    f.write_text(SHARED.replace("mechanism: 5pus_upu", f"mechanism: {desc}"))
    study = load_study(f)
    first = study_class(study)
    m1 = design_mechanism(study, {"link_length": 0.2})
    assert type(m1) is first and study_class(study) is first
    text = desc.read_text()
    desc.write_text(text.replace("slider_min < slider_max", "slider_min < slider_max + 1 m"))
    os.utime(desc, ns=(desc.stat().st_atime_ns, desc.stat().st_mtime_ns + 10**9))
    assert type(design_mechanism(study, {"link_length": 0.21})) is first
    again = load_study(f)
    assert study_class(again) is not first and type(design_mechanism(again, {"link_length": 0.2})) is study_class(again)
    with pytest.raises(ValueError, match=r"unknown parameter\(s\) \['bogus'\]"):
        design_mechanism(study, {"link_length": 0.2, "bogus": 1.0})
