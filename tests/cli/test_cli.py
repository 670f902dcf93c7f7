"""The command line: one-line errors and exit status for bad input and environment faults,
--debug, the schema command, list, evaluate --set warnings, help with examples."""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import re
import sqlite3
import subprocess
import sys
from pathlib import Path

import jsonschema
import pytest
import yaml

import parasynth
import parasynth.cli as cli
from parasynth.cli import main

ROOT = Path(__file__).resolve().parents[2]
STUDIES = sorted((ROOT / "studies").glob("*.yaml"))
QUICK = ROOT / "studies" / "quickstart.yaml"


def run_cli(args, env: dict | None = None):
    """(exit status, stdout, stderr) of ``parasynth ARGS`` run in-process."""
    out, err = io.StringIO(), io.StringIO()
    old = {k: os.environ.get(k) for k in (env or {})}
    os.environ.update(env or {})
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main([str(a) for a in args])
            except SystemExit as e:  # argparse errors and --help
                code = e.code
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return code, out.getvalue(), err.getvalue()


def assert_clean_error(code, err, *needles, status=None):
    assert code not in (0, None), err
    if status is not None:
        assert code == status, (code, err)
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert lines, "no message on stderr"
    assert any(ln.startswith("error:") or ": error:" in ln for ln in lines), err
    for n in needles:
        assert n in err, (n, err)


def tiny_study(tmp_path, **changes) -> Path:
    d = yaml.safe_load(QUICK.read_text())
    d["evaluation"].update(samples=128)
    d["evaluation"].pop("final_samples", None)
    d["optimizer"].update(n_trials=2, population_size=2)
    d.update(changes)
    p = tmp_path / "tiny.yaml"
    p.write_text(yaml.safe_dump(d, sort_keys=False))
    return p


# -- arguments ----------------------------------------------------------------------------------
@pytest.mark.parametrize("args,needle", [
    (["run", QUICK, "--n-trials", "0"], "--n-trials"),
    (["run", QUICK, "--n-trials", "-3"], "--n-trials"),
    (["run", QUICK, "--n-trials", "1e3"], "--n-trials"),
    (["run", QUICK, "--n-trials", "10000001"], "documented maximum"),
    (["run", QUICK, "--out", ""], "--out"),
    (["evaluate", QUICK, "--samples", "-1"], "--samples"),
    (["evaluate", QUICK, "--samples", "10^13"], "--samples"),
    (["evaluate", QUICK, "--samples", "10000000000000"], "documented maximum"),
    (["analyze", "5pus_upu", "--samples", "0"], "--samples"),
    (["analyze", "5pus_upu", "--seed", "-1"], "--seed"),
])
def test_bad_arguments_are_refused_before_any_work(args, needle):
    code, out, err = run_cli(args)
    assert code == 2
    assert needle in err and "Traceback" not in err
    assert out == ""


def test_out_that_is_a_file_is_refused(tmp_path):
    f = tmp_path / "a_file"
    f.write_text("x")
    code, _, err = run_cli(["run", tiny_study(tmp_path), "--out", f, "--quiet"])
    assert_clean_error(code, err, "--out", "existing file", status=2)
    assert f.read_text() == "x"


def test_out_that_cannot_be_created_is_refused(tmp_path):
    f = tmp_path / "a_file"
    f.write_text("x")
    code, _, err = run_cli(["run", tiny_study(tmp_path), "--out", f / "run", "--quiet"])
    assert_clean_error(code, err, "--out", "cannot create", status=2)
    code, _, err = run_cli(["report", tiny_study(tmp_path).parent, "--out", f / "rep"])
    assert "Traceback" not in err and code != 0


# -- files --------------------------------------------------------------------------------------
@pytest.mark.parametrize("content,needle", [
    (b"\xff\xfe\x00n\x00a\x00m\x00e", "binary"),
    (b"name: caf\xe9\n", "not UTF-8"),
    (b"[" * 5000 + b"]" * 5000, "nested deeper"),
    (b"name: a\nname: b\n", "duplicate key 'name'"),
    (b"a: &a [x, x, x, x, x, x, x, x, x, x]\n" + b"".join(
        f"{c}: &{c} [{', '.join(['*' + p] * 10)}]\n".encode() for p, c in zip("abcdefg", "bcdefgh")), "aliases"),
    (b"- just\n- a list\n", "top level"),
    (b"name: [unclosed\n", "not valid YAML"),
])
def test_bad_study_files(tmp_path, content, needle):
    p = tmp_path / "s.yaml"
    p.write_bytes(content)
    for cmd in ("validate", "run", "evaluate"):
        code, _, err = run_cli([cmd, p])
        assert_clean_error(code, err, needle, status=2)


def test_directory_and_missing_file(tmp_path):
    code, _, err = run_cli(["validate", tmp_path])
    assert_clean_error(code, err, "is a directory", status=2)
    code, _, err = run_cli(["validate", tmp_path / "nope.yaml"])
    assert_clean_error(code, err, "does not exist", status=2)


def test_missing_plugin_module():
    code, _, err = run_cli(["list"], env={"PARASYNTH_PLUGINS": "no_such_plugin_module_xyz"})
    assert_clean_error(code, err, "PARASYNTH_PLUGINS", "no_such_plugin_module_xyz")
    code, _, err = run_cli(["list"], env={"PARASYNTH_PLUGINS": "/no/such/plugin.py"})
    assert_clean_error(code, err, "PARASYNTH_PLUGINS", "/no/such/plugin.py")


# -- environment faults, in one place -----------------------------------------------------------
@pytest.mark.parametrize("exc,needle,status", [
    (OSError(errno.ENOSPC, "No space left on device", "runs/x/journal.jsonl"), "disk full", 1),
    (sqlite3.OperationalError("disk I/O error"), "disk I/O error", 1),
    (PermissionError(errno.EACCES, "Permission denied", "runs/x"), "permission denied", 1),
    (MemoryError(), "out of memory", 1),
    (RecursionError("maximum recursion depth exceeded"), "nested too deeply", 2),
    (RuntimeError("something unexpected"), "internal error", 1),
])
def test_faults_during_a_run_give_one_line(tmp_path, monkeypatch, exc, needle, status):
    import parasynth.study as study_pkg

    def boom(*a, **k):
        raise exc

    monkeypatch.setattr(study_pkg, "run_study", boom)
    code, _, err = run_cli(["run", tiny_study(tmp_path), "--out", tmp_path / "r", "--quiet"])
    assert_clean_error(code, err, needle, status=status)
    assert len([ln for ln in err.splitlines() if ln.strip()]) == 1, err


def test_debug_shows_the_traceback(tmp_path, monkeypatch):
    import parasynth.study as study_pkg

    def boom(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(study_pkg, "run_study", boom)
    with pytest.raises(OSError):
        main(["run", str(tiny_study(tmp_path)), "--out", str(tmp_path / "r"), "--quiet", "--debug"])
    with pytest.raises(OSError):
        run_cli(["run", tiny_study(tmp_path), "--out", tmp_path / "r", "--quiet"], env={"PARASYNTH_DEBUG": "1"})


def test_program_exits_with_mains_status_and_all_its_output(tmp_path):
    """The program (``python -m parasynth.cli``, the console script's ``entry``) exits with
    :func:`main`'s status and has written all of main's output by then, on success and on bad
    input alike (it freezes the objects out of the garbage collector before shutting down): the
    same as :func:`main` called in a fresh process with a normal shutdown."""
    import tomllib

    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts == {"parasynth": "parasynth.cli:entry"}
    plain = subprocess.run([sys.executable, "-c", "import sys; from parasynth.cli import main; sys.exit(main(['list']))"],
                           capture_output=True, text=True, timeout=300)
    p = subprocess.run([sys.executable, "-m", "parasynth.cli", "list"], capture_output=True, text=True, timeout=300)
    assert (p.returncode, p.stderr) == (plain.returncode, plain.stderr) == (0, "")
    assert p.stdout == plain.stdout and len(p.stdout) > 1000
    bad = subprocess.run([sys.executable, "-m", "parasynth.cli", "run", str(tmp_path / "missing.yaml")],
                         capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and bad.stdout == ""
    assert bad.stderr.startswith("error: ") and bad.stderr.count("\n") == 1 and "missing.yaml" in bad.stderr

_COUNT_FULL = """
import gc, os, sys
full = []
gc.callbacks.append(lambda phase, info: full.append(1) if phase == "stop" and info["generation"] == 2 else None)
def said():
    sys.stderr.write(f"full collections: {len(full)}\\n")
import atexit
atexit.register(said)
from parasynth import cli
sys.argv = ["parasynth", "validate", sys.argv[1]]
sys.exit(cli.main()) if os.environ.get("VIA") == "main" else cli.entry()
"""


def test_the_program_holds_back_full_collections_while_it_imports():
    """The program collects its oldest generation ten times less often than Python's default
    (cli.FULL_COLLECTION_EVERY): validating the quick start, whose imports (numba, pandas, SciPy)
    set off full collections of everything loaded with the default thresholds (main called in a
    fresh process), sets off none; the validation says the same either way."""
    study = str(ROOT / "studies" / "quickstart.yaml")
    runs = {}
    for via in ("main", "entry"):
        p = subprocess.run([sys.executable, "-c", _COUNT_FULL, study], capture_output=True, text=True, timeout=300,
                           env={**os.environ, "VIA": via})
        assert p.returncode == 0, p.stderr
        said = [ln for ln in p.stderr.splitlines() if ln.startswith("full collections: ")]
        runs[via] = (int(said[-1].split(": ")[1]), p.stdout)
    assert runs["main"][0] >= 1  # with Python's thresholds these imports collect everything at least once
    assert runs["entry"][0] == 0
    assert runs["entry"][1] == runs["main"][1] and "quickstart" in runs["main"][1]


def test_broken_pipe_is_one_line_and_nonzero(tmp_path):
    """``parasynth list | head -2`` in a real pipe: the reader reads a line and goes away while
    the command still writes (list is longer than a pipe buffer): no traceback, status 141."""
    p = subprocess.Popen([sys.executable, "-m", "parasynth.cli", "list"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    first = p.stdout.readline()
    p.stdout.close()  # the reader goes away, as head does
    err = p.stderr.read().decode()
    code = p.wait(timeout=120)
    assert first.startswith(b"mechanisms")
    assert "Traceback" not in err, err
    if code == 0:  # everything was already in the pipe buffer: nothing was lost, nothing to report
        assert err == ""
    else:
        assert code == 141, (code, err)
        assert "broken pipe" in err and err.count("\n") == 1


# -- reports of damaged runs --------------------------------------------------------------------
@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("run")
    d = yaml.safe_load(QUICK.read_text())
    d["evaluation"].update(samples=128, final_samples=128, final_repeats=2, final_top=1)
    d["optimizer"].update(n_trials=3, population_size=2)
    s = tmp / "tiny.yaml"
    s.write_text(yaml.safe_dump(d, sort_keys=False))
    code, out, err = run_cli(["run", s, "--out", tmp / "run", "--quiet", "--no-report"])
    assert code == 0, err
    return tmp / "run"


@pytest.mark.parametrize("name,content", [
    ("results.csv", b"trial,source\n1,2,3,4,5\n\x00\x01"),
    ("final.csv", b"\xff\xfe\x00garbage,\n1,2,3\n4"),
    ("journal.jsonl", b'{"trial": 0, "values": {"link_length": 0.2}\n{not json\n'),
])
def test_report_of_a_damaged_run(small_run, tmp_path, name, content):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(small_run, run)
    if (run / name).exists() or name != "journal.jsonl":
        (run / name).write_bytes(content)
    code, out, err = run_cli(["report", run, "--out", tmp_path / "rep"])
    assert "Traceback" not in err, err
    if code != 0:  # a damaged file is refused with one line naming the run ...
        assert_clean_error(code, err)
    else:  # ... or the report is written from what is still readable
        assert (tmp_path / "rep" / "index.html").exists()


# -- schema, list, evaluate, help ---------------------------------------------------------------
def test_schema_accepts_the_shipped_studies_and_rejects_unknown_keys(tmp_path):
    code, out, err = run_cli(["schema", "--out", tmp_path / "s.json"])
    assert code == 0, err
    schema = json.loads((tmp_path / "s.json").read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    v = jsonschema.Draft202012Validator(schema)
    for f in STUDIES:
        data = yaml.safe_load(f.read_text())
        errors = list(v.iter_errors(data))
        assert not errors, (f.name, [e.message for e in errors])
    bad = yaml.safe_load(QUICK.read_text())
    bad["evaluation"]["sample"] = 10
    assert any("sample" in e.message for e in v.iter_errors(bad))
    bad = yaml.safe_load(QUICK.read_text())
    bad["optimizer"]["kind"] = "annealing"
    assert list(v.iter_errors(bad))
    # every key has a description for the editor
    def props(node):
        for k, p in node.get("properties", {}).items():
            yield k, p
    for node in [schema] + list(schema["$defs"].values()):
        for k, p in props(node):
            assert p.get("description") and "See docs" not in p["description"], k


def test_schema_to_stdout_is_json():
    code, out, _ = run_cli(["schema"])
    assert code == 0
    assert json.loads(out)["title"] == "parasynth study"


def test_study_format_doc_lists_every_key():
    from parasynth.study.spec import study_keys

    doc = (ROOT / "docs" / "study-format.md").read_text()
    missing = [k for k in study_keys() if f"`{k}`" not in doc]
    assert not missing, missing


def test_list_shows_parameters_with_units_and_measure_settings():
    import dataclasses

    from parasynth.mechanisms import list_mechanisms, mechanism_class
    from parasynth.measures.objectives import OBJECTIVES

    code, out, _ = run_cli(["list"])
    assert code == 0
    for name in list_mechanisms():
        block = out.split(f"  {name}:", 1)[1].split("\n  ", 1)[0] if f"  {name}:" in out else ""
        assert block, name
        for f in dataclasses.fields(mechanism_class(name).Params):
            assert f"      {f.name} (" in out, (name, f.name)
    assert re.search(r"link_length \(length, mm(, > 0 mm)?\) = 205 mm", out)
    for name, m in OBJECTIVES.items():
        for k in m.settings:
            assert re.search(rf"^  {re.escape(name)} .*\n      settings: .*\b{k} \(", out, re.M), (name, k)
    assert "quantile (float in [0.0, 1.0])" in out


def test_evaluate_set_outside_bounds_warns(tmp_path):
    s = tiny_study(tmp_path)
    code, out, err = run_cli(["evaluate", s, "--set", "link_length=300 mm", "--samples", "128"])
    assert code == 0, err
    assert "warning: --set link_length=300 mm is outside" in err and "[160 mm, 240 mm]" in err
    code, out, err = run_cli(["evaluate", s, "--set", "link_length=200 mm", "--samples", "128"])
    assert code == 0 and "warning" not in err
    assert "link_length = 200 mm" in out


@pytest.mark.parametrize("item,needle", [
    ("link_length", "NAME=VALUE"),
    ("nope=3 mm", "not a design variable"),
    ("link_length=3", "no unit"),
    ("link_length=nan mm", "finite"),
])
def test_evaluate_bad_set(tmp_path, item, needle):
    code, _, err = run_cli(["evaluate", tiny_study(tmp_path), "--set", item])
    assert_clean_error(code, err, needle, status=2)


def test_every_argument_has_help_with_an_example():
    ap = cli.build_parser()
    sub = next(a for a in ap._actions if isinstance(a, cli.argparse._SubParsersAction))
    for name, p in sub.choices.items():
        assert "example" in (p.epilog or ""), name
        for a in p._actions:
            if a.dest in ("help", "debug"):
                continue
            assert a.help, (name, a.dest)
            assert "e.g." in a.help or "example" in a.help, (name, a.dest, a.help)


def test_run_all_checks_every_study_before_running_any(tmp_path):
    folder = tmp_path / "studies"
    folder.mkdir()
    good = yaml.safe_load(QUICK.read_text())
    good["evaluation"].update(samples=64)
    good["evaluation"].pop("final_samples", None)
    good["optimizer"].update(n_trials=2, population_size=2)
    (folder / "a_good.yaml").write_text(yaml.safe_dump(good))
    bad = copy_of(good, name="b_bad")
    bad["evaluation"]["seed"] = -1
    (folder / "b_bad.yaml").write_text(yaml.safe_dump(bad))
    code, out, err = run_cli(["run-all", folder, "--runs", tmp_path / "runs", "--reports", tmp_path / "reports",
                              "--quiet"])
    assert_clean_error(code, err, "b_bad.yaml", "evaluation.seed", status=2)
    assert not (tmp_path / "runs" / "quickstart").exists()


def copy_of(d, **changes):
    out = json.loads(json.dumps(d))
    out.update(changes)
    return out


def test_python_dash_m_parasynth_is_the_command():
    """``python -m parasynth`` runs the same command line as the ``parasynth`` script: its version
    line names the package's version, and a wrong command exits 2 with argparse's message."""
    ok = subprocess.run([sys.executable, "-m", "parasynth", "--version"], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.strip() == f"parasynth {parasynth.__version__}"
    bad = subprocess.run([sys.executable, "-m", "parasynth", "no-such-command"], capture_output=True, text=True)
    assert bad.returncode == 2
    assert "invalid choice" in bad.stderr and "no-such-command" in bad.stderr
