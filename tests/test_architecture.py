"""The layers of ``src/parasynth`` go one way.

The import graph is built from the source (every ``import``/``from ... import`` of parasynth's
own modules, at module level or inside functions, plus ``importlib.import_module("...")`` and
``__import__("...")`` calls with a literal name), then checked:

* no import cycle between modules;
* every module lies in one of the layered packages (``common``, ``model``, ``engine``,
  ``mechanisms``, ``measures`` and ``export``, ``structures``, ``study``, ``report``, ``cli``), and
  every import stays in its package or goes down: the NumPy model imports only the
  foundations, the engine never the description language;
* the study layer never imports the report layer; the report reads a run through the study
  layer's public run-directory module only;
* the export package imports neither the study nor the report layer;
* at most 10 imports of parasynth's own modules sit inside functions outside ``cli/__init__.py``, each
  with a one-line reason on its line or the line above.

The tests of the checker itself build small synthetic packages, so a checker that found
nothing could not pass them.
"""
from __future__ import annotations

import ast
from dataclasses import dataclass, field
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
MAX_INNER = 10

#: the packages from the bottom up; a module imports only its own package and those below it
#: (``measures`` and ``export`` share a height and never import each other)
LAYERS = (("parasynth.common",), ("parasynth.model",), ("parasynth.engine",), ("parasynth.mechanisms",),
          ("parasynth.measures", "parasynth.export"), ("parasynth.structures",), ("parasynth.study",),
          ("parasynth.report",), ("parasynth.cli",))


@dataclass
class Graph:
    modules: dict[str, Path]
    edges: dict[str, set[str]] = field(default_factory=dict)
    inner: list[tuple[str, int, str, str]] = field(default_factory=list)  # (module, line, target, reason)


def _module_names(root: Path, package: str) -> dict[str, Path]:
    mods = {}
    for p in sorted((root / package).rglob("*.py")):
        rel = p.relative_to(root).with_suffix("")
        name = ".".join(rel.parts)
        if name.endswith(".__init__"):
            name = name[: -len(".__init__")]
        mods[name] = p
    return mods


def _own(name: str, mods: dict) -> str | None:
    """The longest module of ours that ``name`` names or lies in, else None."""
    while name:
        if name in mods:
            return name
        if "." not in name:
            return None
        name = name.rsplit(".", 1)[0]
    return None


def _targets(mod: str, node, mods: dict) -> list[str]:
    is_pkg = mods[mod].name == "__init__.py"
    pkg = mod if is_pkg else mod.rsplit(".", 1)[0]
    out = []
    if isinstance(node, ast.Import):
        out = [a.name for a in node.names]
    elif isinstance(node, ast.ImportFrom):
        base = node.module or ""
        if node.level:
            parts = pkg.split(".")
            parts = parts[: len(parts) - node.level + 1]
            base = ".".join(parts + ([base] if base else []))
        out = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
    elif isinstance(node, ast.Call):
        f = node.func
        fname = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)
        if fname in ("import_module", "__import__") and node.args and isinstance(node.args[0], ast.Constant) \
                and isinstance(node.args[0].value, str):
            name = node.args[0].value
            if name.startswith(".") and len(node.args) > 1 and isinstance(node.args[1], ast.Constant):
                name = node.args[1].value + name
            out = [name]
    return [t for t in (_own(o, mods) for o in out) if t is not None]


def _is_import(node) -> bool:
    if isinstance(node, (ast.Import, ast.ImportFrom)):
        return True
    if isinstance(node, ast.Call):
        f = node.func
        return (f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)) in ("import_module", "__import__")
    return False


def _reason(lines: list[str], lineno: int) -> str:
    """The comment on the import's line or the line above it."""
    for i in (lineno - 1, lineno - 2):
        if 0 <= i < len(lines) and "#" in lines[i]:
            return lines[i].split("#", 1)[1].strip()
    return ""


def build_graph(root: Path, package: str = "parasynth") -> Graph:
    mods = _module_names(root, package)
    g = Graph(mods, {m: set() for m in mods})
    for m, p in mods.items():
        text = p.read_text()
        lines = text.splitlines()
        tree = ast.parse(text)
        in_func: set[int] = set()
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                for node in ast.walk(fn):
                    if _is_import(node):
                        in_func.add(id(node))
        for node in ast.walk(tree):
            if not _is_import(node):
                continue
            for t in sorted(set(_targets(m, node, mods))):
                if t == m or t == package:
                    continue
                g.edges[m].add(t)
                if id(node) in in_func and not m.endswith(".cli"):
                    g.inner.append((m, node.lineno, t, _reason(lines, node.lineno)))
    return g


def cycles(g: Graph) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index, low, stack, on, comps = {}, {}, [], set(), []
    counter = 0
    for start in g.edges:
        if start in index:
            continue
        work = [(start, iter(sorted(g.edges[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on.add(start)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(g.edges[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        comps.append(sorted(comp))
    return comps


def _imports_of(g: Graph, prefix: str) -> dict[str, set[str]]:
    return {m: t for m, t in g.edges.items() if m == prefix or m.startswith(prefix + ".")}


# ---------------------------------------------------------------------------------------------
# the checker on synthetic packages: it finds what it must find
# ---------------------------------------------------------------------------------------------
def _package(tmp_path: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        p = tmp_path / "pkg" / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return tmp_path


def test_checker_finds_a_cycle_hidden_in_a_function(tmp_path):
    root = _package(tmp_path, {
        "__init__.py": "",
        "a.py": "from . import b\n",
        "b.py": "def f():\n    from .a import x  # hidden\n    return x\n",
        "c.py": "import pkg.a\n",
    })
    g = build_graph(root, "pkg")
    assert cycles(g) == [["pkg.a", "pkg.b"]]
    assert g.inner == [("pkg.b", 2, "pkg.a", "hidden")]


def test_checker_counts_importlib_and_dunder_import(tmp_path):
    root = _package(tmp_path, {
        "__init__.py": "",
        "a.py": "import importlib\ndef f():\n    return importlib.import_module('pkg.sub.b')\n",
        "sub/__init__.py": "",
        "sub/b.py": "def g():\n    return __import__('pkg.a')\n",
    })
    g = build_graph(root, "pkg")
    assert g.edges["pkg.a"] == {"pkg.sub.b"} and g.edges["pkg.sub.b"] == {"pkg.a"}
    assert cycles(g) == [["pkg.a", "pkg.sub.b"]]
    assert len(g.inner) == 2


def test_checker_resolves_relative_imports_from_packages(tmp_path):
    root = _package(tmp_path, {
        "__init__.py": "",
        "sub/__init__.py": "from .x import y\nfrom .. import top\n",
        "sub/x.py": "y = 1\n",
        "top.py": "",
    })
    g = build_graph(root, "pkg")
    assert g.edges["pkg.sub"] == {"pkg.sub.x", "pkg.top"}
    assert cycles(g) == []


# ---------------------------------------------------------------------------------------------
# the real package
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def graph() -> Graph:
    g = build_graph(SRC)
    assert len(g.modules) > 30, "the package was not found where the test looks for it"
    return g


def test_no_import_cycles(graph):
    assert cycles(graph) == []


def _package_of(module: str) -> str:
    for height in LAYERS:
        for pkg in height:
            if module == pkg or module.startswith(pkg + "."):
                return pkg
    return None


TOP = ("parasynth", "parasynth._compat")  # the public surface and the flat paths of earlier releases
ENTRY = "parasynth.__main__"  # ``python -m parasynth``: above the CLI, imported by nothing


def _height(pkg: str) -> int:
    return next(i for i, h in enumerate(LAYERS) if pkg in h)


def test_every_module_lies_in_a_package_of_the_layers(graph):
    loose = sorted(m for m in graph.modules if _package_of(m) is None and m not in TOP + (ENTRY,))
    assert loose == [], f"modules outside the layered packages: {loose}"


def upward_imports(graph) -> list[str]:
    up = []
    for m, targets in graph.edges.items():
        here = _package_of(m)
        if here is None:  # the top imports anything
            continue
        for t in targets:
            there = _package_of(t)
            if there != here and _height(there) >= _height(here):
                up.append(f"{m} -> {t}")
    return sorted(up)


def test_checker_finds_upward_and_sideways_imports(tmp_path):
    root = _package(tmp_path, {"__init__.py": "", "model/__init__.py": "", "measures/__init__.py": "",
                               "export/__init__.py": "", "study/__init__.py": "",
                               "model/legs.py": "from ..study import run\n",
                               "measures/w.py": "from ..export import x\nfrom ..model import legs\n"})
    (root / "parasynth").mkdir()
    for p in (root / "pkg").rglob("*.py"):  # the checker knows the package by the name parasynth
        q = root / "parasynth" / p.relative_to(root / "pkg")
        q.parent.mkdir(parents=True, exist_ok=True)
        q.write_text(p.read_text())
    g = build_graph(root, "parasynth")
    assert upward_imports(g) == ["parasynth.measures.w -> parasynth.export", "parasynth.model.legs -> parasynth.study"]


def test_imports_go_down_the_packages(graph):
    """No upward arrow: every import stays in its package or goes to a lower one (the model
    imports only the foundations, the engine never the descriptions, ...)."""
    up = upward_imports(graph)
    assert up == [], "imports that do not go down the layers:\n" + "\n".join(sorted(up))


def test_imports_name_modules_that_exist():
    """Inside the package, every import of ``parasynth...`` names a module where it lies now
    (the flat paths of earlier releases resolve only for users' code, through parasynth._compat)."""
    mods = _module_names(SRC, "parasynth")
    bad = []
    for m, p in mods.items():
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("parasynth")):
                base = node.module or ""
                if node.level:
                    pkg = m if p.name == "__init__.py" else m.rsplit(".", 1)[0]
                    parts = pkg.split(".")
                    base = ".".join(parts[: len(parts) - node.level + 1] + ([base] if base else []))
                if base not in mods:
                    bad.append(f"{m}:{node.lineno} from {base}")
            elif isinstance(node, ast.Import):
                bad += [f"{m}:{node.lineno} import {a.name}" for a in node.names
                        if a.name.startswith("parasynth.") and a.name not in mods]
    assert bad == [], bad


def test_the_flat_paths_of_earlier_releases_are_the_same_modules():
    import importlib

    import parasynth
    from parasynth import _compat

    for old, new in _compat.MOVED.items():
        assert importlib.import_module(old) is importlib.import_module(new), old
        assert importlib.import_module(old).__spec__.name == new, old
    assert callable(parasynth.workspace) and parasynth.workspace is parasynth.measures.workspace.workspace
    from parasynth.objectives import register  # documented for plugins
    from parasynth.workspace import WorkspaceSample

    assert register is parasynth.measures.objectives.register
    assert WorkspaceSample is parasynth.measures.workspace.WorkspaceSample


def test_study_layer_never_imports_the_report(graph):
    for m, targets in _imports_of(graph, "parasynth.study").items():
        bad = sorted(t for t in targets if t.startswith("parasynth.report"))
        assert bad == [], f"{m} (study layer) imports {bad}"


def test_the_export_imports_neither_the_study_nor_the_report(graph):
    for m, targets in _imports_of(graph, "parasynth.export").items():
        bad = sorted(t for t in targets if t.startswith(("parasynth.study", "parasynth.report", "parasynth.cli")))
        assert bad == [], f"{m} (export) imports {bad}"
    assert "parasynth.study.rundir" in graph.edges["parasynth.cli.export_cmd"]  # the run is read there


def test_nothing_below_the_cli_imports_it(graph):
    for m, targets in graph.edges.items():
        assert "parasynth.cli" not in targets or m.startswith("parasynth.cli.") or m == ENTRY, f"{m} imports the CLI"
        assert ENTRY not in targets, f"{m} imports the entry point {ENTRY}"


def test_few_function_level_imports_each_with_a_reason(graph):
    listing = "\n".join(f"  {m}:{line} -> {t}  # {why}" for m, line, t, why in graph.inner)
    assert len(graph.inner) <= MAX_INNER, f"{len(graph.inner)} imports of our own modules inside functions:\n{listing}"
    missing = [(m, line) for m, line, _, why in graph.inner if not why]
    assert missing == [], f"function-level imports without a one-line reason: {missing}"


def test_the_report_reads_runs_through_one_study_module(graph):
    for m, targets in _imports_of(graph, "parasynth.report").items():
        study = sorted(t for t in targets if t.startswith("parasynth.study"))
        assert set(study) <= {"parasynth.study.rundir"}, f"{m} imports {study}"


def test_rotation_entry_names_are_defined_once():
    """``R_NAMES`` is defined in the model layer (``parasynth.model.spatial``) and only imported by
    the engine and the descriptions."""
    defs = []
    for path in (SRC / "parasynth").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.Assign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                if any(isinstance(t, ast.Name) and t.id == "R_NAMES" for t in targets):
                    defs.append(path.relative_to(SRC).as_posix())
    assert defs == ["parasynth/model/spatial.py"]
    from parasynth.model import spatial
    from parasynth.engine import program
    from parasynth.mechanisms.description import expressions

    assert program.R_NAMES is spatial.R_NAMES is expressions.R_NAMES
    assert spatial.R_NAMES == ("R11", "R12", "R13", "R21", "R22", "R23", "R31", "R32", "R33")


def test_no_package_attribute_hides_a_submodule():
    """A function named like a submodule of its package (``cli.cmd_export`` beside a module
    ``cli/cmd_export.py``) is replaced by the module the first time the module is imported."""
    import importlib
    import types

    clashes = []
    for m, p in _module_names(SRC, "parasynth").items():
        if p.name != "__init__.py":
            continue
        pkg = importlib.import_module(m)
        for sub in p.parent.iterdir():
            name = sub.stem if sub.suffix == ".py" else sub.name if (sub / "__init__.py").exists() else None
            if name and name != "__init__" and not isinstance(getattr(pkg, name, types), types.ModuleType):
                clashes.append(f"{m}.{name}")
    assert clashes == [], clashes
