"""One Optuna study on several processes: local ``--workers``, a real PostgreSQL server with a
worker killed mid-trial, and the one-line messages for bad storage input.

The PostgreSQL tests use ``PARASYNTH_TEST_POSTGRES_URL`` (``.ci/run`` starts a server and sets
it); without it they start a throw-away server themselves (initdb and pg_ctl on loopback, in a
temporary directory) and are skipped, with the reason, when that is not possible.
"""

import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd
import pytest
import yaml

from parasynth.cli.plugins import load_plugins
from parasynth.study import StudyError, load_study, run_study

PLUGIN = str(Path(__file__).resolve().parents[1] / "data" / "analytic_plugin.py")
load_plugins(PLUGIN)
ENV = {**os.environ, "PARASYNTH_PLUGINS": PLUGIN, "PARASYNTH_HEARTBEAT": "1"}


def study_dict(name, n, delay=0.0, algorithm="nsga2", duplicates=False):
    variables = [{"name": "link_length", "low": "150 mm", "high": "250 mm"},
                 {"name": "slider_radius", "low": "100 mm", "high": "180 mm"}]
    if duplicates:  # 4 possible designs: the sampler proposes identical designs often
        variables = [{"name": "link_length", "type": "categorical", "choices": ["180 mm", "200 mm"]},
                     {"name": "slider_radius", "type": "categorical", "choices": ["120 mm", "140 mm"]}]
    return {"name": name, "mechanism": "5pus_upu", "variables": variables,
            "objectives": [{"name": "test_quadratic", "goal": "maximize", "settings": {"delay": delay}},
                           {"name": "test_two"}],
            "evaluation": {"samples": 64},
            "optimizer": {"kind": "optuna", "algorithm": algorithm, "n_trials": n, "seed": 0, "population_size": 6}}


def cli(*args):
    return [sys.executable, "-m", "parasynth.cli", *map(str, args)]


def main_in_process(capsys, monkeypatch, *args):
    """``parasynth ARGS`` in this process (no interpreter start-up): (exit code, stdout, stderr)."""
    from parasynth.cli import main

    monkeypatch.setenv("PARASYNTH_PLUGINS", PLUGIN)
    capsys.readouterr()
    try:
        code = main([str(a) for a in args])
    except SystemExit as e:
        code = e.code
    out, err = capsys.readouterr()
    return code, out, err


# -- local worker processes ----------------------------------------------------------------------------
@pytest.mark.parametrize("start", ["fork", "spawn"])
def test_local_workers_record_every_trial_once_identical_designs_included(tmp_path, monkeypatch, capsys, start):
    """Workers forked from the run (the default on Linux with a file storage and one thread
    per worker) or started as ``parasynth worker`` processes: every trial recorded once."""
    import optuna

    from parasynth.study import workers
    from parasynth.study.storage import counts, open_storage

    monkeypatch.setenv("PARASYNTH_PLUGINS", PLUGIN)
    monkeypatch.setenv("NUMBA_NUM_THREADS", "1")  # read by the workers only (numba is loaded)
    if start == "fork":
        if not sys.platform.startswith("linux"):
            pytest.skip("workers are forked on Linux only")

        def no_spawn(*a, **k):
            raise AssertionError("a worker was spawned, not forked")

        monkeypatch.setenv("PARASYNTH_SPAWN_WORKERS", "0")
        monkeypatch.setattr(workers.subprocess, "Popen", no_spawn)
    else:
        monkeypatch.setenv("PARASYNTH_SPAWN_WORKERS", "1")
    s = load_study(yaml.safe_dump(study_dict("local_workers", 24, delay=0.05, algorithm="random",
                                             duplicates=True)), is_text=True)
    res = run_study(s, out_dir=tmp_path / "r", progress=False, workers=2)
    t = res.table[res.table.source == "run"]
    assert sorted(t["trial"]) == list(range(24)), "a trial was lost or recorded twice"
    n_distinct = len(t[["link_length", "slider_radius"]].drop_duplicates())
    assert n_distinct <= 4 < len(t)  # identical designs are all kept
    assert "24 designs evaluated (24 in this run" in res.summary(s)
    st = optuna.load_study(study_name="local_workers", storage=open_storage(f"journal:{tmp_path / 'r' / 'optuna.journal'}"))
    assert sum(counts(x) for x in st.trials) == 24
    owners = {x.user_attrs.get("parasynth:owner") for x in st.trials}
    assert len(owners) == 2, f"both workers evaluate designs: {owners}"
    on_disk = pd.read_csv(tmp_path / "r" / "results.csv")
    assert sorted(on_disk[on_disk.source == "run"]["trial"]) == list(range(24))


def test_two_workers_asking_for_the_last_place_one_is_given_it():
    """Two workers both saw one place left in the budget and asked for a trial at once: the
    lower-numbered trial is evaluated, the other is failed unevaluated and does not count."""
    import optuna
    from optuna.trial import TrialState

    from parasynth.study import workers
    from parasynth.study.storage import ATTR_OVER_BUDGET, counts

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    st = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    for _ in range(2):
        t = st.ask()
        t.suggest_float("x", 0, 1)
        st.tell(t, 1.0)
    first, second = st.ask(), st.ask()  # both running: the budget of 3 has one place left
    assert workers.within_budget(st, first.number, 3)
    assert not workers.within_budget(st, second.number, 3)
    assert workers.within_budget(st, second.number, 4)  # a larger budget has room for both
    evaluated = []

    def objective(trial):
        evaluated.append(trial.number)
        return 0.5

    ran = workers.run_one_trial(st, objective, admit=lambda tr: workers.within_budget(st, tr.number, 3))
    assert ran is None and evaluated == []  # the third running trial asks: refused unevaluated
    refused = st.trials[-1]
    assert refused.state == TrialState.FAIL and refused.user_attrs.get(ATTR_OVER_BUDGET) is True
    assert not counts(refused)
    st.tell(second, state=TrialState.FAIL)  # the refused worker's own trial, failed
    st.tell(first, state=TrialState.FAIL)  # the admitted trial's worker died: the place is free again
    number = workers.run_one_trial(st, objective, admit=lambda tr: workers.within_budget(st, tr.number, 3))
    assert number is not None and evaluated == [number]
    assert sum(counts(t) for t in st.trials) == 3


def test_a_rungs_last_place_per_structure_goes_to_one_trial():
    """A study over structures: a structure whose rung target is taken (by counted and running
    lower-numbered trials) refuses a further trial of it, while the study's total still has
    room; a trial of another structure is admitted."""
    import optuna

    from parasynth.study import workers
    from parasynth.study.schedule import ATTR_STRUCTURE

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    st = optuna.create_study()

    def ask(structure):
        t = st.ask()
        st._storage.set_trial_system_attr(t._trial_id, ATTR_STRUCTURE, structure)
        return t

    done = ask("A")
    st.tell(done, 1.0)
    ask("A")  # running
    third, other = ask("A"), ask("B")
    targets = {"A": 2, "B": 2}
    assert not workers.within_budget(st, third.number, 4, targets)  # A has its 2
    assert workers.within_budget(st, third.number, 4)  # the total alone would have let it in
    assert workers.within_budget(st, other.number, 4, targets)


def test_sweeps_and_nlopt_say_they_run_in_one_process(tmp_path, capsys):
    d = study_dict("one_process", 3)
    d["variables"] = [{"name": "link_length", "values": ["180 mm", "200 mm"]}]
    d["objectives"] = d["objectives"][:1]
    d["optimizer"] = {"kind": "sweep"}
    s = load_study(yaml.safe_dump(d), is_text=True)
    res = run_study(s, out_dir=tmp_path / "r", progress=False, workers=2)
    assert "runs in one process" in capsys.readouterr().err
    assert len(res.table) == 2
    with pytest.raises(StudyError, match="--storage applies to Optuna studies"):
        run_study(s, out_dir=tmp_path / "r2", progress=False, storage="sqlite:///x.db")


# -- bad storage input: one clear line before any work --------------------------------------------------
def _free_port():
    with socket.socket() as so:
        so.bind(("127.0.0.1", 0))
        return so.getsockname()[1]


@pytest.mark.parametrize("url, fragment", [
    ("postgresql://u:secret@127.0.0.1:{port}/db", "cannot reach the server"),
    ("postgresql+pg8000://u:secret@127.0.0.1:{port}/db", "pip install pg8000"),
    ("nosuchdb://u@h/db", "unknown database kind"),
    ("postgresql://u:secret@127.0.0.1:notaport/db", "storage"),
])
def test_bad_storage_one_line_before_work(tmp_path, capsys, monkeypatch, url, fragment):
    pytest.importorskip("psycopg2")
    url = url.format(port=_free_port())
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(study_dict("bad_storage", 4)))
    code, _, err = main_in_process(capsys, monkeypatch, "run", path, "--out", tmp_path / "r", "--storage", url,
                                   "--quiet", "--no-report")
    assert code == 2
    lines = [x for x in err.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: storage"), err
    assert fragment in lines[0]
    assert "secret" not in err  # the password is not shown
    assert not list((tmp_path / "r").glob("journal.jsonl")) or not (tmp_path / "r" / "journal.jsonl").read_text()


def test_worker_with_wrong_study_name(tmp_path):
    url = f"journal:{tmp_path / 'j.journal'}"
    s = load_study(yaml.safe_dump(study_dict("present", 2)), is_text=True)
    run_study(s, out_dir=tmp_path / "r", progress=False, storage=url)
    path = tmp_path / "other.yaml"
    path.write_text(yaml.safe_dump(study_dict("absent", 2)))
    r = subprocess.run(cli("worker", path, "--storage", url, "--quiet"), env=ENV, capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 2
    assert "no study named 'absent'" in r.stderr and "'present'" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_worker_gives_up_after_retries_when_the_storage_is_lost(monkeypatch):
    """A storage that stops answering: a few retries, then a clear error, nothing half-written
    on our side."""
    from sqlalchemy.exc import OperationalError

    from parasynth.study import workers

    class Lost:
        calls = 0

        _storage = None

        def ask(self, *a, **k):
            Lost.calls += 1
            raise OperationalError("SELECT 1", {}, Exception("server closed the connection unexpectedly"))

        def get_trials(self, deepcopy=False):
            return []

    monkeypatch.setattr(workers.time, "sleep", lambda s: None)
    objective = lambda t: 0.0  # noqa: E731
    objective.stats = {"records": 0}
    logs = []
    with pytest.raises(workers.StorageLost, match="gave up after 3 retries"):
        workers.optimize_loop(Lost(), objective, 10, workers.Interrupt(), shared=False, retries=3, log=logs.append)
    assert Lost.calls == 4 and len(logs) == 3 and "retrying in 4 s" in logs[-1]


# -- a real PostgreSQL server -------------------------------------------------------------------------------
def _start_postgres():
    """A throw-away server: (url, stop) or raises RuntimeError with the reason."""
    bindirs = sorted(Path("/usr/lib/postgresql").glob("*/bin")) if Path("/usr/lib/postgresql").exists() else []
    initdb = next((d / "initdb" for d in reversed(bindirs) if (d / "initdb").exists()), None)
    if initdb is None and shutil.which("initdb"):
        initdb = Path(shutil.which("initdb"))
    if initdb is None:
        raise RuntimeError("no PostgreSQL server binaries (initdb) on this machine; install postgresql")
    bindir = initdb.parent
    tmp = Path(tempfile.mkdtemp(prefix="parasynth-pg-"))
    prefix = []
    if os.geteuid() == 0:  # the server refuses to run as root
        import pwd

        for user in ("postgres", "nobody"):
            try:
                pw = pwd.getpwnam(user)
                break
            except KeyError:
                pw = None
        if pw is None:
            raise RuntimeError("running as root and no unprivileged user (postgres, nobody) to run the server")
        os.chown(tmp, pw.pw_uid, pw.pw_gid)
        runuser = shutil.which("runuser") or shutil.which("su")
        if runuser is None:
            raise RuntimeError("running as root without runuser/su to start the server as another user")
        prefix = [runuser, "-u", user, "--"] if runuser.endswith("runuser") else None
        if prefix is None:
            raise RuntimeError("need runuser to start the server as an unprivileged user")
    password = "pw" + os.urandom(6).hex()
    pwfile = tmp / "pw"
    pwfile.write_text(password + "\n")
    if os.geteuid() == 0:
        os.chown(pwfile, pw.pw_uid, pw.pw_gid)
    port = _free_port()
    run = lambda *cmd: subprocess.run(prefix + [str(c) for c in cmd], capture_output=True, text=True,  # noqa: E731
                                      timeout=120, cwd=tmp)
    r = run(bindir / "initdb", "-D", tmp / "data", "-U", "parasynth", f"--pwfile={pwfile}", "-A", "scram-sha-256")
    if r.returncode:
        raise RuntimeError(f"initdb failed: {r.stderr.strip()[-300:]}")
    def start():
        r = run(bindir / "pg_ctl", "-D", tmp / "data", "-l", tmp / "log", "-w", "-t", "60",
                "-o", f"-c listen_addresses=127.0.0.1 -p {port} -k {tmp} -c fsync=off", "start")
        if r.returncode:
            raise RuntimeError(f"pg_ctl start failed: {(r.stderr or r.stdout).strip()[-300:]}")

    def halt():
        run(bindir / "pg_ctl", "-D", tmp / "data", "-m", "immediate", "-w", "stop")

    def stop():
        halt()
        shutil.rmtree(tmp, ignore_errors=True)

    start()
    stop.halt, stop.start = halt, start

    env = {**os.environ, "PGPASSWORD": password}
    r = subprocess.run(prefix + [str(bindir / "createdb"), "-h", "127.0.0.1", "-p", str(port), "-U", "parasynth",
                                 "parasynth_test"], capture_output=True, text=True, env=env, timeout=60, cwd=tmp)
    if r.returncode:
        stop()
        raise RuntimeError(f"createdb failed: {r.stderr.strip()[-300:]}")
    return f"postgresql://parasynth:{password}@127.0.0.1:{port}/parasynth_test", stop


@pytest.fixture(scope="module")
def postgres_url():
    pytest.importorskip("psycopg2", reason="the PostgreSQL driver is not installed: pip install psycopg2-binary")
    url = os.environ.get("PARASYNTH_TEST_POSTGRES_URL")
    if url:
        yield url
        return
    try:
        url, stop = _start_postgres()
    except (RuntimeError, OSError, subprocess.SubprocessError) as e:
        pytest.skip(f"no PostgreSQL server for the tests: {e}")
    try:
        yield url
    finally:
        stop()


def _trials(url, name):
    import optuna

    from parasynth.study.storage import open_storage

    return optuna.load_study(study_name=name, storage=open_storage(url, heartbeat=False)).get_trials(deepcopy=False)


def test_postgres_three_workers_one_killed_mid_trial(tmp_path, postgres_url):
    """3 processes on one study (the run and 2 workers); one worker is SIGKILLed while it
    evaluates: every completed trial is stored once, none is lost, the killed trial is failed
    (and retried), the study reaches its budget, and the run's results equal the storage."""
    from optuna.trial import TrialState

    from parasynth.study.storage import counts

    import optuna

    from parasynth.study.storage import open_storage

    name = f"pg_kill_{os.getpid()}"
    n = 24
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(study_dict(name, n, delay=0.5, algorithm="random")))
    storage = open_storage(postgres_url, heartbeat=False)

    def stored():
        return optuna.load_study(study_name=name, storage=storage).get_trials(deepcopy=False)

    out = tmp_path / "run"
    run = subprocess.Popen(cli("run", path, "--out", out, "--storage", postgres_url, "--quiet", "--no-report"),
                           env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline:  # the run has created the study
        try:
            if stored():
                break
        except Exception:
            pass
        time.sleep(0.2)
    workers = [subprocess.Popen(cli("worker", path, "--storage", postgres_url, "--quiet"), env=ENV,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    victim = workers[0]
    owner = f"{socket.gethostname()}:{victim.pid}"
    killed_trial = None
    deadline = time.time() + 60
    while time.time() < deadline and killed_trial is None:
        for t in stored():
            if t.state == TrialState.RUNNING and t.user_attrs.get("parasynth:owner") == owner:
                killed_trial = t.number  # in its 0.5 s evaluation
                victim.send_signal(signal.SIGKILL)
                break
        time.sleep(0.02)
    assert killed_trial is not None, "the worker never started a trial"
    victim.wait()
    _, err = workers[1].communicate(timeout=120)
    assert workers[1].returncode == 0, err
    stdout, err = run.communicate(timeout=120)
    assert run.returncode == 0, err
    trials = stored()
    killed = [t for t in trials if t.number == killed_trial][0]
    assert killed.state == TrialState.FAIL and not counts(killed)
    counted = [t for t in trials if counts(t)]
    assert n <= len(counted) <= n + 2  # the budget is reached (workers finishing together may add one each)
    assert not [t for t in trials if t.state in (TrialState.RUNNING, TrialState.WAITING)]
    # None lost, none twice: the run's table holds exactly the counted trials of the server.
    table = pd.read_csv(out / "results.csv")
    run_rows = table[table.source == "run"]
    assert sorted(run_rows["trial"]) == sorted(t.number for t in counted)
    assert run_rows["trial"].is_unique
    # All three processes evaluated designs.
    owners = {t.user_attrs.get("parasynth:owner") for t in counted}
    assert len(owners) >= 2
    # The report can be rebuilt from the server alone.
    from parasynth.cli import main

    assert main(["report", "--storage", postgres_url, "--study", name, "--run-dir", str(tmp_path / "rebuilt"),
                 "--out", str(tmp_path / "rep")]) == 0
    rebuilt = pd.read_csv(tmp_path / "rebuilt" / "results.csv")
    pd.testing.assert_frame_equal(rebuilt.drop(columns="time_s"), table.drop(columns="time_s"))
    assert (tmp_path / "rep" / "index.html").exists()


def test_postgres_wrong_credentials_one_line(tmp_path, capsys, monkeypatch, postgres_url):
    from sqlalchemy.engine import make_url

    bad = make_url(postgres_url).set(password="wrong").render_as_string(hide_password=False)
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(study_dict("pg_bad_password", 2)))
    code, _, err = main_in_process(capsys, monkeypatch, "run", path, "--out", tmp_path / "r", "--storage", bad,
                                   "--quiet", "--no-report")
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "refused the credentials" in lines[0] and "wrong" not in lines[0]


def test_a_storage_whose_tables_another_process_is_creating_opens_on_a_later_attempt(tmp_path, monkeypatch):
    """Workers started together on a new database race to create Optuna's tables: the loser's
    CREATE TABLE collides with the winner's (PostgreSQL: a unique violation on pg_type). Opening
    the storage tries again and succeeds once the tables exist; any other error, or a collision
    that does not go away, is the one-line storage error at once or after the last attempt."""
    import optuna.storages
    from sqlalchemy.exc import IntegrityError

    from parasynth.study import storage as st

    race = IntegrityError("CREATE TABLE studies (...)", {}, Exception(
        'duplicate key value violates unique constraint "pg_type_typname_nsp_index"'))
    calls = []

    def opening(fail: int, error=race):
        def rdb(url, **kw):
            calls.append(url)
            if len(calls) <= fail:
                raise error
            return "storage"
        return rdb

    monkeypatch.setattr(st.time, "sleep", lambda s: None)
    url = f"sqlite:///{tmp_path / 'o.db'}"
    monkeypatch.setattr(optuna.storages, "RDBStorage", opening(2))
    assert st.open_storage(url, heartbeat=False) == "storage" and len(calls) == 3
    calls.clear()
    monkeypatch.setattr(optuna.storages, "RDBStorage", opening(st.SCHEMA_ATTEMPTS))
    with pytest.raises(st.StorageError, match="cannot use it as an Optuna storage .*duplicate key"):
        st.open_storage(url, heartbeat=False)
    assert len(calls) == st.SCHEMA_ATTEMPTS
    calls.clear()
    monkeypatch.setattr(optuna.storages, "RDBStorage", opening(1, RuntimeError("incompatible schema version")))
    with pytest.raises(st.StorageError, match="incompatible schema version"):
        st.open_storage(url, heartbeat=False)
    assert len(calls) == 1


def test_postgres_workers_opening_a_new_database_together(postgres_url):
    """Four storages opened at the same moment on a new PostgreSQL database (as workers started
    together): every one opens, and the study one of them creates is seen by the others."""
    import threading

    import optuna
    from sqlalchemy import create_engine, text

    from parasynth.study.storage import open_storage

    name = f"parasynth_new_{os.getpid()}_{int(time.time() * 1000) % 100000}"
    admin = create_engine(postgres_url.replace("postgresql://", "postgresql+psycopg2://", 1), isolation_level="AUTOCOMMIT")
    with admin.connect() as c:
        c.execute(text(f"CREATE DATABASE {name}"))
    url = postgres_url.rsplit("/", 1)[0] + "/" + name
    try:
        start = threading.Barrier(4)
        got, errors = [], []

        def worker():
            start.wait()
            try:
                got.append(open_storage(url, heartbeat=False))
            except Exception as e:  # noqa: BLE001 - collected and shown below
                errors.append(e)

        threads = [threading.Thread(target=worker) for _ in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=120)
        assert not errors, errors
        assert len(got) == 4
        optuna.create_study(study_name="together", storage=got[0])
        assert [s.study_name for s in got[3].get_all_studies()] == ["together"]
        for s in got:
            s.engine.dispose()
    finally:
        with admin.connect() as c:
            c.execute(text(f"DROP DATABASE IF EXISTS {name} WITH (FORCE)"))
        admin.dispose()


def test_postgres_worker_wrong_study_name(tmp_path, capsys, monkeypatch, postgres_url):
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(study_dict(f"pg_never_started_{os.getpid()}", 2)))
    code, _, err = main_in_process(capsys, monkeypatch, "worker", path, "--storage", postgres_url, "--quiet")
    assert code == 2
    assert "holds no study named" in err and len(err.strip().splitlines()) == 1


def test_postgres_lost_server_worker_retries_then_exits_and_resume_completes(tmp_path):
    """The database server goes away under a running study: the run retries a few times, exits
    with one clear message and its tables written; with the server back, --resume completes
    the study with every trial once."""
    pytest.importorskip("psycopg2", reason="the PostgreSQL driver is not installed: pip install psycopg2-binary")
    try:
        url, stop = _start_postgres()  # a server of its own: this test stops it
    except (RuntimeError, OSError, subprocess.SubprocessError) as e:
        pytest.skip(f"no PostgreSQL server for the tests: {e}")
    try:
        name = "pg_lost"
        path = tmp_path / "s.yaml"
        path.write_text(yaml.safe_dump(study_dict(name, 20, delay=0.2, algorithm="random")))
        out = tmp_path / "run"
        env = {**ENV, "PARASYNTH_STORAGE_RETRIES": "2"}
        cmd = cli("run", path, "--out", out, "--storage", url, "--quiet", "--no-report")
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.time() + 60
        while time.time() < deadline:
            p = out / "journal.jsonl"
            if p.exists() and len(p.read_text().splitlines()) >= 3:
                break
            time.sleep(0.05)
        stop.halt()
        t0 = time.time()
        _, err = proc.communicate(timeout=90)
        assert proc.returncode == 2, err
        assert time.time() - t0 < 30  # 2 retries (1 s, 2 s) and the connection timeouts, not a hang
        msg = [x for x in err.splitlines() if x.startswith("error:")]
        assert len(msg) == 1 and "lost the storage" in msg[0] and "Traceback" not in err
        assert "retrying in 1 s" in err
        noise = [x for x in err.splitlines() if x.strip() and not x.startswith(("error:", "storage error"))]
        assert not noise, err
        saved = pd.read_csv(out / "results.csv")
        assert len(saved) >= 3
        stop.start()
        r = subprocess.run(cmd + ["--resume"], env=env, capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stderr
        import optuna

        from parasynth.study.storage import counts, open_storage

        trials = optuna.load_study(study_name=name, storage=open_storage(url, heartbeat=False)).trials
        counted = [t.number for t in trials if counts(t)]
        assert len(counted) == 20
        table = pd.read_csv(out / "results.csv")
        assert sorted(table["trial"]) == sorted(counted)
    finally:
        stop()


def test_trial_abandoned_before_its_owner_was_recorded_is_failed(monkeypatch):
    """A process that stopped between asking for a trial and recording its owner (the storage went
    away then) leaves a running trial that neither the owner check nor the heartbeat can fail:
    after ORPHAN_AGE_S it is failed, so a resumed run does not wait for it forever."""
    import optuna
    from optuna.trial import TrialState

    from parasynth.study import workers

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    ostudy = optuna.create_study()
    orphan = ostudy.ask()  # running, no owner
    owned = ostudy.ask()
    owned.set_user_attr(workers.OWNER_ATTR, f"{socket.gethostname()}:{os.getpid()}")  # alive: this process
    monkeypatch.setattr(workers, "ORPHAN_AGE_S", 3600.0)
    assert workers.budget_state(ostudy) == (0, 2, 0)  # young: may still be a live worker's
    monkeypatch.setattr(workers, "ORPHAN_AGE_S", 0.0)
    assert workers.budget_state(ostudy) == (0, 1, 0)
    states = {t.number: t.state for t in ostudy.get_trials(deepcopy=False)}
    assert states == {orphan.number: TrialState.FAIL, owned.number: TrialState.RUNNING}


# -- optuna-dashboard ------------------------------------------------------------------------------------
def _dashboard_get(app, path: str):
    """GET ``path`` from a WSGI app (the dashboard's own routes): (status, parsed JSON)."""
    import io
    import json
    from wsgiref.util import setup_testing_defaults

    env = {"PATH_INFO": path, "REQUEST_METHOD": "GET", "wsgi.input": io.BytesIO()}
    setup_testing_defaults(env)
    seen = {}
    body = b"".join(app(env, lambda status, headers, exc_info=None: seen.setdefault("status", status)))
    return seen["status"], json.loads(body)


def test_optuna_dashboard_reads_a_runs_journal_with_the_objective_names(tmp_path):
    """optuna-dashboard opens a run's journal file with its own storage loader (the path given as
    on its command line, ``optuna-dashboard runs/NAME/optuna.journal``) and names the objectives
    by the study's labels, for a run of one process and one of local workers."""
    from _optional import DASHBOARD, import_or_skip

    dashboard = import_or_skip("optuna_dashboard", DASHBOARD, "optuna-dashboard")
    for workers in (1, 2):
        spec = study_dict(f"dash_{workers}", 6, algorithm="random")
        spec["objectives"][0]["label"] = "quadratic"
        run_study(load_study(yaml.safe_dump(spec), is_text=True), out_dir=tmp_path / str(workers), progress=False,
                  workers=workers)
        app = dashboard.wsgi(str(tmp_path / str(workers) / "optuna.journal"))
        status, listing = _dashboard_get(app, "/api/studies")
        assert status.startswith("200"), status
        (summary,) = listing["study_summaries"]
        assert summary["study_name"] == f"dash_{workers}"
        status, detail = _dashboard_get(app, f"/api/studies/{summary['study_id']}")
        assert status.startswith("200"), status
        assert detail["objective_names"] == ["quadratic", "test_two"]
        done = [t for t in detail["trials"] if t["state"] == "Complete"]
        assert len(done) == 6, [t["state"] for t in detail["trials"]]  # the budget, exactly: workers never exceed it
