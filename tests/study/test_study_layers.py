"""The study and report layers: one definition per concept, and imports that go one way."""

import ast
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from parasynth.study import defaults
from parasynth.study.design import box_centre, centre_value, design_key, design_params
from parasynth.study.spec import Variable

SRC = Path(__file__).resolve().parents[2] / "src" / "parasynth"


def _study(*variables, **kw):
    return SimpleNamespace(variables=variables, fixed=kw.get("fixed", {}), tied=kw.get("tied", {}),
                           objectives=kw.get("objectives", ()), evaluation={"seed": 7},
                           optimizer=SimpleNamespace(**{"algorithm": None, "n_trials": None, "maxeval": None,
                                                        "seed": None, "kind": "optuna", "designs": None,
                                                        **kw.get("opt", {})}))


def test_box_centre_respects_log_scale_and_integers():
    lin = Variable("a", "continuous", "length", 0.1, 0.4)
    log = Variable("b", "continuous", "length", 0.1, 0.4, log=True)
    integer = Variable("n", "integer", None, 3, 8)
    int_log = Variable("m", "integer", None, 1, 100, log=True)
    swept = Variable("s", "continuous", "length", None, None, values=(0.1, 0.2, 0.3))
    cat = Variable("c", "categorical", None, choices=("x", "y"))
    c = box_centre(_study(lin, log, integer, int_log, swept, cat))
    assert c["a"] == pytest.approx(0.25)
    assert c["b"] == pytest.approx(0.2)  # the geometric mean on a log scale, not 0.25
    assert c["n"] == 6 and isinstance(c["n"], int)  # round(5.5) (bankers' rounding: 6)
    assert c["m"] == 10 and isinstance(c["m"], int)  # the geometric centre of [1, 100]
    assert c["s"] == 0.2 and c["c"] == "x"
    assert centre_value(log) == pytest.approx(log.denormalize(0.5))


def test_design_key_survives_csv_round_trip(tmp_path):
    study = _study(Variable("a", "continuous", "length", 0.1, 0.4), Variable("n", "integer", None, 1, 9),
                   Variable("c", "categorical", None, choices=("x", "y")))
    values = {"a": 0.1 + 0.2 / 3, "n": 4, "c": "y"}
    pd.DataFrame([values]).to_csv(tmp_path / "t.csv", index=False)
    row = pd.read_csv(tmp_path / "t.csv").iloc[0]
    assert design_key(study, values) == design_key(study, row)
    assert design_key(study, {**values, "a": values["a"] * (1 + 1e-9)}) != design_key(study, values)
    assert isinstance(design_key(study, {**values, "n": np.int64(4)})[1], int)
    # kept roundings give what formatting gives, the sign of a zero included
    rng = np.random.default_rng(3)
    xs = np.concatenate([rng.uniform(-1, 1, 300) * 10.0 ** rng.integers(-12, 12, 300), [0.0, -0.0, 5e-324]])
    for _ in range(2):
        for x in xs:
            got = design_key(study, {**values, "a": np.float64(x)})[0]
            want = float(f"{float(x):.12g}")
            assert got == want and math.copysign(1.0, got) == math.copysign(1.0, want)


def test_design_keys_of_a_table_are_the_rows_keys(tmp_path):
    """``final.design_keys`` (the rows read as dicts) gives each row's ``design_key`` as a row of
    ``iterrows`` does: floats to 12 digits, integers, categories, an inactive (empty) value,
    read back from CSV, and a variable without a column; so the merged duplicates and the front
    are those of the rows."""
    from parasynth.study.final import design_keys, merge_duplicates

    study = _study(Variable("a", "continuous", "length", 0.1, 0.4), Variable("n", "integer", None, 1, 9),
                   Variable("c", "categorical", None, choices=("x", "y")), Variable("z", "continuous", None, 0, 1))
    rows = [{"a": 0.1 + 0.2 / 3, "n": 4, "c": "y"}, {"a": 0.2, "n": 5, "c": "x", "z": 0.5},
            {"a": (0.1 + 0.2 / 3) * (1 + 1e-14), "n": 4, "c": "y"}, {"a": 0.2, "n": 5, "c": "x", "z": np.nan}]
    pd.DataFrame(rows).assign(v=[1.0, 2.0, 3.0, 4.0]).to_csv(tmp_path / "t.csv", index=False)
    table = pd.read_csv(tmp_path / "t.csv")
    for df in (table, table.drop(columns="z")):
        keys = design_keys(study, df)
        assert keys == [design_key(study, r) for _, r in df.iterrows()]
        assert keys[0] == keys[2] and (keys[1] != keys[3]) == ("z" in df)
    merged = merge_duplicates(study, table)
    assert merged["v"].tolist() == [1.0, 2.0, 4.0] and merged["count"].tolist() == [2, 1, 1]


def test_design_params_adds_fixed_and_tied():
    study = _study(Variable("a", "continuous", "length", 0.1, 0.4), fixed={"r": 0.3}, tied={"b": "a"})
    assert design_params(study, {"a": 0.2}) == {"r": 0.3, "a": 0.2, "b": 0.2}


def test_defaults_in_one_place():
    one = _study(objectives=(1,))
    two = _study(objectives=(1, 2))
    assert defaults.optuna_algorithm(one) == "tpe" and defaults.optuna_algorithm(two) == "nsga2"
    assert defaults.optuna_budget(one) == defaults.OPTUNA_TRIALS == 50
    assert defaults.optuna_budget(one, 7) == 7 and defaults.optuna_budget(one, None, stored=9) == 9
    assert defaults.nlopt_budget(one) == 100 and defaults.nlopt_algorithm(one) == "LN_COBYLA"
    assert defaults.optimizer_seed(one) == 7 and defaults.optimizer_seed(_study(opt={"seed": 3})) == 3
    assert defaults.planned_designs(one) == 50


# -- imports -------------------------------------------------------------------------------------------
def _module(path: Path) -> str:
    rel = path.relative_to(SRC.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(path: Path):
    """(target module, inside a function?) for every import of the package's own modules."""
    mod = _module(path)
    pkg = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]
    tree = ast.parse(path.read_text())
    inner = {id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
             for n in ast.walk(f)}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("parasynth")):
            base = node.module or ""
            if node.level:
                parts = pkg.split(".")[: len(pkg.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            for a in node.names:
                full = f"{base}.{a.name}"
                target = full if (SRC.parent / (full.replace(".", "/") + ".py")).exists() else base
                out.append((target, id(node) in inner))
        elif isinstance(node, ast.Import):
            out += [(a.name, id(node) in inner) for a in node.names if a.name.startswith("parasynth")]
    return out


LAYERS = sorted((SRC / "study").glob("*.py")) + sorted((SRC / "report").glob("*.py")) + [SRC / "common" / "pareto.py"]


def test_study_layer_never_imports_the_report_layer():
    for p in sorted((SRC / "study").glob("*.py")) + [SRC / "common" / "pareto.py"]:
        bad = [t for t, _ in _imports(p) if t.startswith("parasynth.report")]
        assert not bad, f"{_module(p)} imports {bad}"


def test_report_reads_runs_through_rundir_only():
    for p in sorted((SRC / "report").glob("*.py")):
        study = {t for t, _ in _imports(p) if t.startswith("parasynth.study")}
        assert study <= {"parasynth.study.rundir"}, f"{_module(p)} imports {study}"


def test_no_own_imports_inside_functions_and_no_cycles():
    graph = {}
    for p in LAYERS:
        imps = _imports(p)
        inner = [t for t, fn in imps if fn]
        assert not inner, f"{_module(p)} imports {inner} inside a function"
        graph[_module(p)] = {t for t, _ in imps if t in {_module(q) for q in LAYERS}} - {_module(p)}
    # a package imports its submodules (__init__ re-exports); cycles are looked for among modules
    state = {}

    def visit(m, stack):
        state[m] = 1
        for t in graph.get(m, ()):
            if t in (m.rsplit(".", 1)[0],):
                continue
            if state.get(t) == 1:
                pytest.fail("import cycle: " + " -> ".join(stack + [m, t]))
            if t not in state:
                visit(t, stack + [m])
        state[m] = 2

    for m in graph:
        if m not in state:
            visit(m, [])


def test_optuna_private_interfaces_only_in_the_adapter():
    for p in sorted((SRC / "study").glob("*.py")) + [SRC / "cli" / "study_cmd.py"]:
        if p.name == "optuna_adapter.py":
            continue
        text = p.read_text()
        for private in ("._storage", "._trial_id", "._study_id", "storages._", "_log_number_offset"):
            assert private not in text, f"{p.name} uses Optuna's private {private}"


def test_importing_the_study_layer_leaves_heavy_packages_unloaded():
    import subprocess
    import sys

    code = ("import sys, parasynth.study, parasynth.report, parasynth.study.rundir; "
            "print(sorted(m for m in ('optuna', 'nlopt', 'matplotlib', 'sqlalchemy') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_math_is_used():  # the log-scale centre is the geometric mean
    v = Variable("b", "continuous", "length", 0.1, 0.4, log=True)
    assert centre_value(v) == pytest.approx(math.sqrt(0.1 * 0.4))
