"""Contract tests run over every registered optimiser (:mod:`parasynth.study.optimizers`): the
declared attributes agree with the spec and the schema, a run evaluates designs only through the
Problem and within the budget, a resumed run repeats no evaluated design, bad input is refused
by name; and the optimiser kind is compared with a string literal in few places of the source."""

import re
from pathlib import Path

import pytest

from parasynth.study import OPTIMIZERS, StudySpec, load_study
from parasynth.study.evaluate import Record
from parasynth.study.optimizers import BaseOptimizer, optimizer_class, registered
from parasynth.study.problem import Problem, RunContext
from parasynth.study.spec import OptimizerSpec, StudyError

SRC = Path(__file__).resolve().parents[2] / "src" / "parasynth"
KINDS = list(registered())

STUDY = """
name: contract_{kind}
mechanism: 5pus_upu
variables:
  - {{name: link_length, low: 160 mm, high: 240 mm, num: 3}}
  - {{name: slider_radius, low: 110 mm, high: 170 mm, num: 3}}
objectives: [{{name: workspace_volume, label: volume, goal: maximize}}]
evaluation:
  samples: 256
  seed: 0
  ranges: {{x: [-200 mm, 200 mm], y: [-200 mm, 200 mm], z: [-450 mm, 300 mm]}}
optimizer: {{kind: {kind}, seed: 3}}
"""


class Analytic(Problem):
    """The study's space with an analytic objective, maximum 1 at (0.21 m, 0.125 m); counts calls."""

    def __init__(self, study):
        super().__init__(study)
        self.calls = []

    def evaluate(self, values, trial=-1, source="run", n=None, seed=None):
        self.calls.append(dict(values))
        f = 1.0 - ((values["link_length"] - 0.21) / 0.08) ** 2 - ((values["slider_radius"] - 0.125) / 0.06) ** 2
        return Record(values=dict(values), objectives={"volume": f}, trial=trial, source=source)


def _run(kind, tmp_path, records, n_trials, resume=False):
    problem = Analytic(load_study(STUDY.format(kind=kind), is_text=True))
    opt = optimizer_class(kind)()
    records = opt.open(problem, tmp_path, resume, n_trials, None, list(records))
    new = []

    def record(rec):
        records.append(rec)
        new.append(rec)

    opt.run(problem, RunContext(records, record, n_trials=n_trials, out_dir=tmp_path))
    return problem, records, new


@pytest.mark.parametrize("kind", KINDS)
def test_declared_attributes_agree_with_the_spec_and_schema(kind):
    cls = optimizer_class(kind)
    assert issubclass(cls, BaseOptimizer) and cls.kind == kind
    assert cls.algorithms and all(isinstance(a, str) for a in cls.algorithms)
    assert OPTIMIZERS[kind] == cls.algorithms
    assert cls.budget_key is None or cls.budget_key in OptimizerSpec.model_fields
    assert cls.title and cls.description
    enum = StudySpec.model_json_schema()["$defs"]["OptimizerSpec"]["properties"]["kind"]["enum"]
    assert kind in enum


@pytest.mark.parametrize("kind", KINDS)
def test_a_run_evaluates_through_the_problem_within_the_budget(kind, tmp_path):
    cls = optimizer_class(kind)
    n = None if cls.lists_designs else 8
    problem, records, new = _run(kind, tmp_path, [], n)
    budget = problem.budget(n)
    assert 0 < len(new) <= budget
    assert len(problem.calls) == len(new)  # every record came from problem.evaluate
    assert all(r.source == "run" for r in new)
    assert len({r.trial for r in new}) == len(new)
    for r in new:  # within the bounds
        assert 0.16 - 1e-12 <= r.values["link_length"] <= 0.24 + 1e-12
        assert 0.11 - 1e-12 <= r.values["slider_radius"] <= 0.17 + 1e-12


@pytest.mark.parametrize("kind", KINDS)
def test_a_resumed_run_repeats_no_evaluated_design(kind, tmp_path):
    cls = optimizer_class(kind)
    if cls.lists_designs:
        _, first, _ = _run(kind, tmp_path, [], None)
        first = first[:4]  # interrupted after four designs
        problem, records, new = _run(kind, tmp_path, first, None, resume=True)
        assert len(new) == cls.planned_designs(problem.study) - 4
    else:
        _, first, _ = _run(kind, tmp_path, [], 5)
        problem, records, new = _run(kind, tmp_path, first, 9, resume=True)
        assert len([r for r in records if r.source == "run"]) <= 9
    seen = {problem.space.key(r.values) for r in first}
    assert not [c for c in problem.calls if problem.space.key(c) in seen and cls.kind != "optuna"]
    assert {r.trial for r in new}.isdisjoint({r.trial for r in first})


@pytest.mark.parametrize("kind", KINDS)
def test_an_unknown_algorithm_is_refused_by_name(kind):
    text = STUDY.format(kind=kind).replace(f"kind: {kind},", f"kind: {kind}, algorithm: no_such_alg,")
    with pytest.raises(StudyError, match=r"optimizer\.algorithm: 'no_such_alg'.*allowed: " + re.escape(
            optimizer_class(kind).algorithms[0])):
        load_study(text, is_text=True)


def test_an_unknown_kind_names_the_registered_ones():
    with pytest.raises(StudyError, match=r"optimizer\.kind.*" + ".*".join(KINDS)):
        load_study(STUDY.format(kind="annealing"), is_text=True)


@pytest.mark.parametrize("kind", KINDS)
def test_a_study_over_structures_is_run_or_refused_by_name(kind):
    cls = optimizer_class(kind)
    opt = OptimizerSpec(kind=kind)
    if cls.runs_structures:
        cls.check_structures(opt)
    else:
        with pytest.raises(StudyError, match="optimizer.kind"):
            cls.check_structures(opt)


KIND_LITERAL = re.compile(r"""kind\s*(==|!=)\s*["']({k})["']|["']({k})["']\s*(==|!=)\s*\S*kind|kind\s+(not\s+)?in\s*"""
                          r"""[(\[{{][^)\]}}]*["']({k})["']""".format(k="|".join(KINDS)))


def test_the_optimizer_kind_is_compared_with_a_literal_in_few_places():
    hits = []
    for path in SRC.rglob("*.py"):
        for i, line in enumerate(path.read_text().splitlines(), 1):
            if KIND_LITERAL.search(line):
                hits.append(f"{path.relative_to(SRC)}:{i}: {line.strip()}")
    assert len(hits) <= 3, "\n".join(hits)


def test_the_literal_check_can_fail():
    assert KIND_LITERAL.search('if study.optimizer.kind == "optuna":')
    assert KIND_LITERAL.search("if opt.kind in ('nlopt', 'optuna') and x:")


def test_study_format_doc_describes_every_registered_optimiser():
    doc = (SRC.parents[1] / "docs" / "study-format.md").read_text()
    for kind, cls in registered().items():
        row = next((line for line in doc.splitlines() if line.startswith(f"| `{kind}` |")), None)
        assert row is not None, f"docs/study-format.md has no row for optimizer.kind {kind}"
        assert cls.description in row, kind
        assert all(a in row for a in cls.algorithms), kind


def test_the_base_class_is_abstract():
    with pytest.raises(TypeError):
        BaseOptimizer()
