"""The design space: typed variables, the unit cube, the centre, the grid, Optuna suggestion,
conditional variables and the SI values of given designs."""

import pandas as pd
import pytest

from parasynth.study import StudyError, load_study
from parasynth.study.problem import Problem
from parasynth.study.space import DesignSpace, Variable, design_key
from parasynth.study.tables import results_table
from parasynth.study.evaluate import Record

BASE = """
name: space_test
mechanism: 5pus_upu
objectives: [{name: workspace_volume, label: volume, goal: maximize}]
evaluation: {samples: 64}
"""


def _study(variables: str, optimizer: str = "{kind: sweep}", extra: str = ""):
    return load_study(BASE + "variables:\n" + variables + f"optimizer: {optimizer}\n" + extra, is_text=True)


CONDITIONAL = """  - {name: hinge_layout, type: categorical, choices: [scheme1, scheme2]}
  - {name: link_length, values: [180 mm, 200 mm]}
  - {name: hinge_scale, values: [0.8, 1.0, 1.2], when: {hinge_layout: [scheme2]}}
"""


def test_unit_cube_round_trip_log_and_integer():
    lin = Variable("a", "continuous", "length", 0.1, 0.4)
    log = Variable("b", "continuous", "length", 0.01, 1.0, log=True)
    integer = Variable("n", "integer", None, 3, 9)
    int_log = Variable("m", "integer", None, 1, 1000, log=True)
    cat = Variable("c", "categorical", None, choices=("x", "y"))
    space = DesignSpace([lin, log, integer, int_log, cat])
    assert [v.name for v in space.numeric] == ["a", "b", "n", "m"]
    assert space.bounds() == [(0.1, 0.4), (0.01, 1.0), (3, 9), (1, 1000)]
    values = {"a": 0.325, "b": 0.1, "n": 6, "m": 10}
    u = space.to_unit(values)
    assert u == pytest.approx([0.75, 0.5, 0.5, 1 / 3])  # log scale: 0.1 is the middle of [0.01, 1]
    back = space.from_unit(u)
    assert back["a"] == pytest.approx(0.325) and back["b"] == pytest.approx(0.1)
    assert back["n"] == 6 and isinstance(back["n"], int) and back["m"] == 10 and isinstance(back["m"], int)
    assert space.from_unit([-1, 2, 0.01, 0.99]) == pytest.approx({"a": 0.1, "b": 1.0, "n": 3, "m": 933})
    for x in (0.0, 0.13, 0.77, 1.0):
        assert space.to_unit(space.from_unit([x, x, 0, 0]) | {"n": 3, "m": 1})[:2] == pytest.approx([x, x])


def test_centre_is_log_aware_and_drops_inactive_variables():
    space = DesignSpace([Variable("b", "continuous", "length", 0.01, 1.0, log=True),
                         Variable("c", "categorical", None, choices=("x", "y")),
                         Variable("k", "integer", None, 2, 5, when=(("c", ("y",)),))])
    assert space.centre() == pytest.approx({"b": 0.1, "c": "x"})  # k is inactive for the first choice
    space2 = DesignSpace([Variable("c", "categorical", None, choices=("y", "x")),
                          Variable("k", "integer", None, 2, 5, when=(("c", ("y",)),))])
    assert space2.centre() == {"c": "y", "k": 4}  # round(3.5)


def test_grid_with_a_conditional_variable():
    study = _study(CONDITIONAL)
    space = study.space
    assert space.variables[2].when == (("hinge_layout", ("scheme2",)),)
    grid = space.grid()
    # scheme1: 2 link lengths; scheme2: 2 link lengths x 3 hinge scales
    assert len(grid) == space.grid_size() == 2 + 2 * 3 == 8
    assert len({design_key(space.variables, d) for d in grid}) == 8
    assert [d for d in grid if d["hinge_layout"] == "scheme1"] == [
        {"hinge_layout": "scheme1", "link_length": pytest.approx(0.18)},
        {"hinge_layout": "scheme1", "link_length": pytest.approx(0.2)}]
    assert all(("hinge_scale" in d) == (d["hinge_layout"] == "scheme2") for d in grid)
    assert list(grid[-1]) == ["hinge_layout", "link_length", "hinge_scale"]  # the study's order
    # without conditions the grid is the plain product, first variable slowest
    plain = _study(CONDITIONAL.replace(", when: {hinge_layout: [scheme2]}", "")).space
    assert plain.grid_size() == len(plain.grid()) == 12
    assert [d["hinge_layout"] for d in plain.grid()] == ["scheme1"] * 6 + ["scheme2"] * 6
    # an inactive variable is absent from the design and empty in the results table
    table = results_table(study, [Record(values=grid[0], trial=0)])
    assert pd.isna(table["hinge_scale"][0])
    assert table.to_csv(index=False).splitlines()[1].split(",")[4] == ""  # trial, source, layout, length, scale
    assert design_key(space.variables, table.iloc[0]) == design_key(space.variables, grid[0])


class FakeTrial:
    """Answers suggestions from a table of values and records what was asked."""

    def __init__(self, answers):
        self.answers, self.asked = answers, []

    def suggest_categorical(self, name, choices):
        self.asked.append((name, "categorical", tuple(choices)))
        return self.answers[name]

    def suggest_int(self, name, low, high, log=False):
        self.asked.append((name, "int", low, high, log))
        return self.answers[name]

    def suggest_float(self, name, low, high, log=False):
        self.asked.append((name, "float", low, high, log))
        return self.answers[name]


def test_suggest_asks_conditional_variables_only_when_active():
    study = _study("""  - {name: hinge_scale, low: 0.5, high: 2.0, log: true, when: {hinge_layout: [scheme2]}}
  - {name: hinge_layout, type: categorical, choices: [scheme1, scheme2]}
  - {name: link_length, low: 160 mm, high: 240 mm}
""", "{kind: optuna, n_trials: 3}")
    space = study.space
    t1 = FakeTrial({"hinge_layout": "scheme1", "link_length": 0.2, "hinge_scale": 1.0})
    assert space.suggest(t1) == {"hinge_layout": "scheme1", "link_length": 0.2}
    assert [a[0] for a in t1.asked] == ["hinge_layout", "link_length"]
    t2 = FakeTrial({"hinge_layout": "scheme2", "link_length": 0.2, "hinge_scale": 1.5})
    assert space.suggest(t2) == {"hinge_scale": 1.5, "hinge_layout": "scheme2", "link_length": 0.2}
    assert t2.asked[0] == ("hinge_layout", "categorical", ("scheme1", "scheme2"))  # the parent first
    assert ("hinge_scale", "float", 0.5, 2.0, True) in t2.asked
    assert ("link_length", "float", pytest.approx(0.16), pytest.approx(0.24), False) in t2.asked


def test_suggest_with_a_real_optuna_trial():
    optuna = pytest.importorskip("optuna")
    optuna.logging.set_verbosity(optuna.logging.ERROR)
    space = _study(CONDITIONAL.replace("values: [0.8, 1.0, 1.2]", "low: 0.8, high: 1.2")
                   .replace("values: [180 mm, 200 mm]", "low: 180 mm, high: 200 mm"), "{kind: optuna}").space
    ostudy = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=3))
    seen = set()
    for _ in range(12):
        trial = ostudy.ask()
        values = space.suggest(trial)
        assert ("hinge_scale" in values) == (values["hinge_layout"] == "scheme2")
        assert set(trial.params) == set(values)
        assert 0.18 <= values["link_length"] <= 0.2
        seen.add(values["hinge_layout"])
        ostudy.tell(trial, 0.0)
    assert seen == {"scheme1", "scheme2"}


@pytest.mark.parametrize("when, where, says", [
    ("{nothing: [a]}", "variables[2].when.nothing", "not a design variable"),
    ("{link_length: [180 mm]}", "variables[2].when.link_length", "categorical"),
    ("{hinge_layout: [scheme9]}", "variables[2].when.hinge_layout[0]", "not a choice"),
    ("{hinge_layout: []}", "variables[2].when.hinge_layout", "non-empty"),
    ("{hinge_scale: [1]}", "variables[2].when.hinge_scale", "itself"),
])
def test_when_errors_name_the_key_path(when, where, says):
    text = CONDITIONAL.replace("{hinge_layout: [scheme2]}", when)
    with pytest.raises(StudyError) as e:
        _study(text)
    assert str(e.value).startswith(where + ":") and says in str(e.value)


def test_when_cycle_is_an_error_and_choices_take_units():
    ok = _study("""  - {name: hinge_layout, type: categorical, choices: [scheme1, scheme2]}
  - {name: link_length, type: categorical, choices: [180 mm, 200 mm], when: {hinge_layout: [scheme1]}}
  - {name: hinge_scale, values: [1.0, 1.1], when: {link_length: [20 cm]}}
""")
    assert ok.space.variables[2].when == (("link_length", (pytest.approx(0.2),)),)
    assert ok.space.grid_size() == len(ok.space.grid()) == 1 + 1 + 2  # scheme2 | scheme1 x (180 | 200 x 2)
    with pytest.raises(StudyError, match=r"^variables\[0\]\.when: the conditions form a cycle: "
                                         r"hinge_layout -> link_length -> hinge_layout"):
        _study("""  - {name: hinge_layout, type: categorical, choices: [scheme1, scheme2], when: {link_length: [180 mm]}}
  - {name: link_length, type: categorical, choices: [180 mm, 200 mm], when: {hinge_layout: [scheme1]}}
""")


NLOPT_VARS = """  - {name: link_length, low: 160 mm, high: 240 mm}
  - {name: slider_radius, low: 110 mm, high: 170 mm}
"""


def test_starts_and_designs_are_parsed_once_with_units():
    study = _study(NLOPT_VARS, "{kind: nlopt, start: {link_length: 20 cm}}")
    problem = Problem(study)
    assert problem.start() == {"link_length": pytest.approx(0.2)}
    assert problem.budget() == 100 and problem.budget(7) == 7
    sweep = _study(NLOPT_VARS, "{kind: sweep, designs: [{link_length: 200 mm, slider_radius: 0.15 m}, "
                               "{link_length: 7.1 in}]}")
    designs = Problem(sweep).designs()
    assert designs == [{"link_length": pytest.approx(0.2), "slider_radius": pytest.approx(0.15)},
                       {"link_length": pytest.approx(0.18034)}]
    assert Problem(sweep).budget() == 2
    assert study.space.parse({"slider_radius": "120 mm"}, "--set") == {"slider_radius": pytest.approx(0.12)}


@pytest.mark.parametrize("optimizer, where", [
    ("{kind: nlopt, start: {link_length: 20 kg}}", "optimizer.start.link_length"),
    ("{kind: nlopt, start: {link_lenght: 200 mm}}", "optimizer.start.link_lenght"),
    ("{kind: sweep, designs: [{link_length: 200 mm}, {slider_radius: 12}]}", "optimizer.designs[1].slider_radius"),
    ("{kind: sweep, designs: [{link_length: 200 mm}, {radius: 12 mm}]}", "optimizer.designs[1].radius"),
])
def test_bad_starts_and_designs_name_the_key_path(optimizer, where):
    with pytest.raises(StudyError) as e:
        _study(NLOPT_VARS, optimizer)
    assert str(e.value).startswith(where)


def test_study_keeps_variables_and_spec_variable_importable():
    from parasynth.study.spec import Variable as SpecVariable

    study = _study(NLOPT_VARS, "{kind: nlopt}")
    assert SpecVariable is Variable
    assert study.space.variables == study.variables
    assert study.space.key({"link_length": 0.2, "slider_radius": 0.13}) == (0.2, 0.13)


def test_a_conditional_sweep_runs_end_to_end(tmp_path):
    import csv

    from parasynth.study import run_study

    text = (BASE.replace("evaluation: {samples: 64}", "evaluation: {samples: 64, final_samples: 64, final_repeats: 1, "
                                                      "final_top: 3}")
            + "fixed: {link_length: 205 mm}\nvariables:\n"
            + "  - {name: hinge_layout, type: categorical, choices: [scheme1, scheme2]}\n"
            + "  - {name: hinge_scale, values: [0.9, 1.1], when: {hinge_layout: [scheme2]}}\n"
            + "optimizer: {kind: sweep}\n")
    study = load_study(text, is_text=True)
    res = run_study(study, out_dir=tmp_path / "run", progress=False)
    assert res.n_new == 3 and not res.interrupted
    rows = list(csv.DictReader(open(tmp_path / "run" / "results.csv")))
    assert [(r["hinge_layout"], r["hinge_scale"]) for r in rows] == [("scheme1", ""), ("scheme2", "0.9"),
                                                                      ("scheme2", "1.1")]
    assert [r["status"] for r in rows] == ["ok"] * 3
    assert res.final is not None and len(res.final)
    # resuming finds every design done
    again = run_study(study, out_dir=tmp_path / "run", resume=True, progress=False)
    assert again.n_new == 0 and again.n_total == 3
