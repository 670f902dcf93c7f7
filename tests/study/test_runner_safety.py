"""Runs that are safe to interrupt and resume: Ctrl-C on a real ``parasynth run``, torn journal
lines, the run-directory lock, and resumed runs equal to uninterrupted ones."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from parasynth.cli.plugins import load_plugins
from parasynth.study import StudyError, load_study, read_journal, run_study
from parasynth.study.journal import JournalError, RunLock, RunLockedError

PLUGIN = str(Path(__file__).resolve().parents[1] / "data" / "analytic_plugin.py")
load_plugins(PLUGIN)
ENV = {**os.environ, "PARASYNTH_PLUGINS": PLUGIN}

VARS = [{"name": "link_length", "low": "150 mm", "high": "250 mm"},
        {"name": "slider_radius", "low": "100 mm", "high": "180 mm"}]


def study_dict(kind, delay=0.0, n=24, algorithm=None):
    d = {"name": f"safety_{kind}", "mechanism": "5pus_upu", "variables": VARS,
         "objectives": [{"name": "test_quadratic", "goal": "maximize", "settings": {"delay": delay}}],
         "evaluation": {"samples": 64}}  # the report's workspace figures stay cheap
    if kind == "optuna":
        d["objectives"].append({"name": "test_two"})
        d["optimizer"] = {"kind": "optuna", "algorithm": algorithm or "nsga2", "n_trials": n, "seed": 0,
                          "population_size": 6}
    elif kind == "nlopt":
        d["optimizer"] = {"kind": "nlopt", "algorithm": "LN_COBYLA", "maxeval": n, "xtol_rel": 1e-12}
    else:
        d["variables"] = [{"name": "link_length", "low": "150 mm", "high": "250 mm", "num": n}]
        d["optimizer"] = {"kind": "sweep"}
    return d


def write_study(tmp_path, d) -> Path:
    p = tmp_path / "study.yaml"
    p.write_text(yaml.safe_dump(d))
    return p


def cli(*args):
    return [sys.executable, "-m", "parasynth.cli", *map(str, args)]


def journal_lines(out: Path):
    p = out / "journal.jsonl"
    return [json.loads(x) for x in p.read_text().splitlines() if x.strip()] if p.exists() else []


def wait_for_lines(out, n, proc, timeout=60):
    deadline = time.time() + timeout
    while time.time() < deadline:
        if len(journal_lines_safe(out)) >= n:
            return
        if proc.poll() is not None:
            raise AssertionError(f"the run ended early: {proc.communicate()}")
        time.sleep(0.05)
    raise AssertionError("the run did not write its journal in time")


def journal_lines_safe(out):
    p = out / "journal.jsonl"
    if not p.exists():
        return []
    return [x for x in p.read_text().splitlines() if x.endswith("}")]


def pareto_rows(df, cols_signs):
    """Brute-force non-dominated rows (NumPy reference, independent of the package)."""
    F = np.column_stack([df[c].to_numpy(float) * s for c, s in cols_signs])
    keep = [i for i in range(len(F))
            if not any(np.all(F[j] <= F[i]) and np.any(F[j] < F[i]) for j in range(len(F)))]
    return df.iloc[keep].sort_values("trial").reset_index(drop=True)


# -- Ctrl-C on a real run ----------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["optuna", "sweep", "nlopt"])
def test_sigint_stops_cleanly_with_partial_report_and_resume_hint(tmp_path, kind):
    path = write_study(tmp_path, study_dict(kind, delay=0.15, n=40))
    out, rep = tmp_path / "run", tmp_path / "report"
    # The partial report is checked on the Optuna run (the others' reports compute workspace
    # figures of the 5-PUS/UPU designs: slow, and the same code path).
    report = ["--report-dir", rep] if kind == "optuna" else ["--no-report"]
    proc = subprocess.Popen(cli("run", path, "--out", out, "--quiet", *report), env=ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for_lines(out, 4, proc)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "Traceback" not in stdout
    assert "--resume" in stderr and str(out) in stderr
    lines = journal_lines(out)  # every line parses: the journal is consistent
    assert 4 <= len(lines) < 40
    run_lines = [x for x in lines if x["source"] == "run"]
    assert len({x["trial"] for x in run_lines}) == len(run_lines)
    table = pd.read_csv(out / "results.csv")
    assert len(table) == len(lines)
    if kind == "optuna":
        assert (rep / "index.html").exists() and "partial report" in stdout
    if kind == "optuna":
        import optuna

        from parasynth.study.storage import counts, open_storage

        st = optuna.load_study(study_name="safety_optuna", storage=open_storage(f"journal:{out / 'optuna.journal'}"))
        assert sum(counts(t) for t in st.trials) == len(run_lines)
    # Resuming completes the run (in process: the same code as the hinted command, faster).
    run_study(load_study(yaml.safe_dump(study_dict(kind, delay=0.15, n=40)), is_text=True), out_dir=out,
              resume=True, progress=False)
    lines = journal_lines(out)
    if kind != "nlopt":  # NLopt may stop on its tolerance before the budget
        assert len([x for x in lines if x["source"] == "run"]) == 40


def test_sigint_reaches_local_workers(tmp_path):
    """Ctrl-C on ``run --workers 2``: the workers finish their designs, the journal equals the
    storage, exit 130."""
    path = write_study(tmp_path, study_dict("optuna", delay=0.2, n=60, algorithm="random"))
    out = tmp_path / "run"
    # one thread per worker: the workers are forked from the run (on Linux), as on 2 cores
    proc = subprocess.Popen(cli("run", path, "--out", out, "--quiet", "--no-report", "--workers", 2),
                            env={**ENV, "NUMBA_NUM_THREADS": "1"},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for_lines(out, 4, proc)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr
    import optuna

    from parasynth.study.storage import counts, open_storage

    st = optuna.load_study(study_name="safety_optuna", storage=open_storage(f"journal:{out / 'optuna.journal'}"))
    assert not [t for t in st.trials if t.state == optuna.trial.TrialState.RUNNING], "a worker was left running"
    stored = sorted(t.number for t in st.trials if counts(t))
    assert sorted(x["trial"] for x in journal_lines(out) if x["source"] == "run") == stored
    assert 4 <= len(stored) < 60


# -- torn journal lines ---------------------------------------------------------------------------------
def test_torn_last_line_is_cut_on_resume(tmp_path, capsys):
    s = load_study(yaml.safe_dump(study_dict("sweep", n=8)), is_text=True)
    fresh = run_study(s, out_dir=tmp_path / "fresh", progress=False).table
    out = tmp_path / "r"
    run_study(s, out_dir=out, progress=False)
    j = out / "journal.jsonl"
    lines = j.read_text().splitlines(keepends=True)
    # A power loss while writing the 6th line: 5 lines intact, half of the 6th.
    j.write_text("".join(lines[:5]) + lines[5][: len(lines[5]) // 2])
    assert len(read_journal(out)) == 5  # readers skip the torn line
    res = run_study(s, out_dir=out, resume=True, progress=False)
    err = capsys.readouterr().err
    assert "cut" in err and "journal.jsonl" in err
    recs = journal_lines(out)  # every line parses: the next record did not land on the torn one
    assert sorted(x["trial"] for x in recs) == list(range(8))
    assert res.n_new == 3
    pd.testing.assert_frame_equal(res.table.drop(columns="time_s"), fresh.drop(columns="time_s"))


def test_damaged_middle_line_names_file_and_line(tmp_path):
    s = load_study(yaml.safe_dump(study_dict("sweep", n=4)), is_text=True)
    out = tmp_path / "r"
    run_study(s, out_dir=out, progress=False)
    j = out / "journal.jsonl"
    lines = j.read_text().splitlines(keepends=True)
    j.write_text(lines[0] + "{not json\n" + "".join(lines[1:]))
    with pytest.raises(JournalError, match=r"journal.jsonl: line 2"):
        run_study(s, out_dir=out, resume=True, progress=False)


# -- one writer per run directory -------------------------------------------------------------------
def test_live_run_holds_the_directory(tmp_path):
    path = write_study(tmp_path, study_dict("optuna", delay=0.15, n=40))
    out = tmp_path / "run"
    first = subprocess.Popen(cli("run", path, "--out", out, "--quiet", "--no-report"), env=ENV,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for_lines(out, 2, first)
    second = subprocess.run(cli("run", path, "--out", out, "--quiet", "--no-report", "--resume"), env=ENV,
                            capture_output=True, text=True, timeout=60)
    assert second.returncode != 0
    assert "in use" in second.stderr and f"pid {first.pid}" in second.stderr
    assert "Traceback" not in second.stderr
    _, err = first.communicate(timeout=60)
    assert first.returncode == 0, err  # the live run was not disturbed
    t = pd.read_csv(out / "results.csv")
    assert sorted(t["trial"]) == list(range(40))


def test_lock_of_a_killed_run_is_not_stuck(tmp_path):
    out = tmp_path / "r"
    out.mkdir()
    code = ("import sys, time; from parasynth.study.journal import RunLock; "
            f"lock = RunLock({str(out)!r}).acquire(); print('locked', flush=True); time.sleep(60)")
    holder = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "locked"
    with pytest.raises(RunLockedError, match=f"pid {holder.pid}"):
        RunLock(out).acquire()
    holder.send_signal(signal.SIGKILL)
    holder.wait()
    lock = RunLock(out).acquire()  # the operating system released the dead holder's lock
    lock.release()
    s = load_study(yaml.safe_dump(study_dict("sweep", n=3)), is_text=True)
    with RunLock(out):
        with pytest.raises(RunLockedError):
            run_study(s, out_dir=out, progress=False)


# -- resume reproduces ----------------------------------------------------------------------------------
def _compare_runs(a: Path, b: Path, objectives):
    ta = pd.read_csv(a / "results.csv").drop(columns="time_s")
    tb = pd.read_csv(b / "results.csv").drop(columns="time_s")
    pd.testing.assert_frame_equal(ta, tb)
    ra, rb = ta[ta.source == "run"], tb[tb.source == "run"]
    pa, pb = pareto_rows(ra, objectives), pareto_rows(rb, objectives)
    assert len(pa) >= 2
    pd.testing.assert_frame_equal(pa, pb)


def test_killed_and_resumed_run_has_the_uninterrupted_pareto_front(tmp_path):
    """SIGKILL mid-trial (a trial left running in the storage), resume: same designs, same
    results table, same Pareto front as the uninterrupted run with the same seed."""
    path = write_study(tmp_path, study_dict("optuna", delay=0.1, n=30))
    out, ref = tmp_path / "killed", tmp_path / "whole"
    proc = subprocess.Popen(cli("run", path, "--out", out, "--quiet", "--no-report"), env=ENV,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wait_for_lines(out, 9, proc)
    time.sleep(0.05)  # inside the next trial's evaluation
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    done = len(journal_lines(out))
    assert 9 <= done < 30
    # Resumed and uninterrupted runs in process (the same code as ``parasynth run``, faster).
    s = load_study(path)
    run_study(s, out_dir=out, resume=True, progress=False)
    run_study(s, out_dir=ref, progress=False)
    _compare_runs(out, ref, [("test_quadratic_m2", -1), ("test_two_m", 1)])  # results.csv names: units as suffixes


@pytest.mark.parametrize("algorithm", ["tpe", "nsga2", "random"])
def test_resume_after_unfinished_trial_equals_uninterrupted(tmp_path, algorithm):
    """In process: a run stopped after 10 designs with an 11th trial left running (as a kill
    leaves it), resumed to 22, equals a run of 22 from the start."""
    import optuna

    from parasynth.study.storage import open_storage

    d = study_dict("optuna", n=22, algorithm=algorithm)
    d["constraints"] = [{"name": "test_link_length", "max": "230 mm"}]
    s = load_study(yaml.safe_dump(d), is_text=True)
    run_study(s, out_dir=tmp_path / "a", progress=False, n_trials=10)
    st = optuna.load_study(study_name=s.name, storage=open_storage(f"journal:{tmp_path / 'a' / 'optuna.journal'}"))
    t = st.ask()
    t.suggest_float("link_length", 0.15, 0.25)
    res = run_study(s, out_dir=tmp_path / "a", progress=False, resume=True, n_trials=22)
    assert res.n_new == 12
    run_study(s, out_dir=tmp_path / "b", progress=False, n_trials=22)
    _compare_runs(tmp_path / "a", tmp_path / "b", [("test_quadratic_m2", -1), ("test_two_m", 1)])  # results.csv names: units as suffixes


KILLER = str(Path(__file__).resolve().parents[1] / "data" / "kill_at_trial.py")


@pytest.mark.parametrize("algorithm,kills", [
    ("nsga2", [(6, "suggest"), (13, "record"), (24, "evaluate")]),
    ("qmc", [(13, "evaluate")]),
])
def test_killed_at_chosen_trials_and_resumed_equals_uninterrupted(tmp_path, algorithm, kills):
    """``parasynth run`` killed (SIGKILL) at chosen trials and points -- NSGA-II: while the
    first trial of a generation stores its variables (trial 6, population 6), after a trial
    stored its record but before it was told (13), while the first trial of a later generation
    is evaluated (24) -- and resumed after each kill: the trial running at each kill is asked
    again with the same values, and results.csv equals the uninterrupted run's (all but
    time_s). The samplers keep state in the study: NSGA-II each generation's parents, QMC its
    point counter."""
    path = write_study(tmp_path, study_dict("optuna", n=30, algorithm=algorithm))
    out, ref = tmp_path / "killed", tmp_path / "whole"
    for i, (trial, point) in enumerate(kills):
        args = ["run", path, "--out", out, "--quiet", "--no-report"] + (["--resume"] if i else [])
        r = subprocess.run([sys.executable, KILLER, *map(str, args)], env={**ENV, "PARASYNTH_TEST_KILL": f"{trial}:{point}"},
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == -signal.SIGKILL, (trial, point, r.returncode, r.stderr)
        lines = [x for x in journal_lines(out) if x["source"] == "run"]
        # the killed trial is not counted (with "record" its line may be in the journal mirror)
        assert trial - 1 <= max(x["trial"] for x in lines) <= trial, (trial, point)
    s = load_study(path)
    res = run_study(s, out_dir=out, resume=True, progress=False)
    assert not res.interrupted and int((res.table["source"] == "run").sum()) == 30
    run_study(s, out_dir=ref, progress=False)
    _compare_runs(out, ref, [("test_quadratic_m2", -1), ("test_two_m", 1)])


@pytest.mark.parametrize("kept_after", [False, True])
def test_rebuild_restores_sampler_state_from_before_the_dropped_trial(tmp_path, kept_after):
    """The rebuilt storage holds the study's system attributes (sampler state) from before the
    first dropped trial was created -- unless a kept trial was written after that (several
    processes): then nothing a kept trial may have relied on is taken back."""
    import optuna

    from parasynth.study.storage import open_storage, rebuild_journal_storage

    url = f"journal:{tmp_path / 'optuna.journal'}"
    st = optuna.create_study(study_name="s", storage=open_storage(url))
    sid = st._study_id
    st._storage.set_study_system_attr(sid, "before", 1)
    t0 = st.ask()
    t0.suggest_float("x", 0, 1)
    if not kept_after:
        st.tell(t0, 0.5)
    t1 = st.ask()  # left running: dropped on resume
    t1.suggest_float("x", 0, 1)
    st._storage.set_study_system_attr(sid, "during", 2)
    st._storage.set_study_system_attr(sid, "before", 3)
    if kept_after:
        st.tell(t0, 0.5)  # written after the dropped trial was created
    st.set_user_attr("kept", "yes")
    assert rebuild_journal_storage(url, "s") == 1
    new = optuna.load_study(study_name="s", storage=open_storage(url))
    attrs = new._storage.get_study_system_attrs(new._study_id)
    assert attrs == ({"before": 3, "during": 2} if kept_after else {"before": 1})
    assert new.user_attrs == {"kept": "yes"}
    assert [(t.number, t.state.name, t.params) for t in new.trials] == [(0, "COMPLETE", t0.params)]


def test_resume_refuses_another_study_in_the_storage(tmp_path):
    s = load_study(yaml.safe_dump(study_dict("optuna", n=4)), is_text=True)
    url = f"journal:{tmp_path / 'shared.journal'}"
    run_study(s, out_dir=tmp_path / "a", progress=False, storage=url)
    with pytest.raises(StudyError, match="already holds a study named 'safety_optuna'.*--resume"):
        run_study(s, out_dir=tmp_path / "b", progress=False, storage=url)


def test_second_sigint_drops_the_design_being_evaluated(tmp_path):
    """Ctrl-C twice during a long evaluation: the design is dropped at once (not recorded),
    the run ends cleanly with exit 130, a consistent journal and the resume hint."""
    path = write_study(tmp_path, study_dict("sweep", delay=4.0, n=3))
    out = tmp_path / "run"
    proc = subprocess.Popen(cli("run", path, "--out", out, "--quiet", "--no-report"), env=ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while not (out / "journal.jsonl").exists() and time.time() < deadline:  # opened just before evaluating
        time.sleep(0.02)
    time.sleep(0.5)  # inside the first 4 s evaluation
    t0 = time.time()
    proc.send_signal(signal.SIGINT)
    time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert time.time() - t0 < 3.0, "the design being evaluated was not dropped"
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "--resume" in stderr
    assert journal_lines(out) == []
