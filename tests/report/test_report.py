"""The report files and the analysis they state (the Pareto maths itself: test_pareto.py)."""

import itertools
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from _optional import BROWSER, find_browser, import_or_skip
from _support import brute_force_front, brute_spread
from parasynth.cli import load_plugins
from parasynth.report import ReportError, write_report
from parasynth.report.summary import run_summary
from parasynth.study import load_study, run_study

PLUGIN = str(Path(__file__).resolve().parents[1] / "data" / "analytic_plugin.py")
load_plugins(PLUGIN)


# -- report files ------------------------------------------------------------------------------------
class _Collector(HTMLParser):
    def __init__(self):
        super().__init__()
        self.imgs, self.tables, self.rows, self.links = [], 0, [], []
        self._in_td, self._row = False, None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.imgs.append(a.get("src", ""))
        if tag in ("link", "script") and (a.get("src") or a.get("href")):
            self.links.append(a.get("src") or a.get("href"))
        if tag == "table":
            self.tables += 1
        if tag == "tr":
            self._row = []
        if tag == "td":
            self._in_td = True

    def handle_endtag(self, tag):
        if tag == "td":
            self._in_td = False
        if tag == "tr" and self._row is not None:
            self.rows.append(self._row)
            self._row = None

    def handle_data(self, data):
        if self._in_td and self._row is not None:
            self._row.append(data)


@pytest.fixture(scope="module")
def mo_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("mo")
    spec = {
        "name": "mo_report",
        "mechanism": "5pus_upu",
        "variables": [{"name": "link_length", "low": "150 mm", "high": "250 mm"},
                      {"name": "slider_radius", "low": "100 mm", "high": "180 mm"}],
        "objectives": [{"name": "test_quadratic"}, {"name": "test_two"}],
        "constraints": [{"name": "test_link_length", "max": "230 mm"}],
        "reference": {"link_length": "205 mm", "slider_radius": "135 mm"},
        "evaluation": {"samples": 256},
        "optimizer": {"kind": "optuna", "algorithm": "nsga2", "n_trials": 40, "seed": 2},
    }
    study = load_study(yaml.safe_dump(spec), is_text=True)
    res = run_study(study, out_dir=d / "run", progress=False)
    out = write_report(d / "run", out=d / "report")
    return study, res, out


def test_report_files_and_pareto_csv(mo_run):
    study, res, out = mo_run
    for f in ("index.html", "report.md", "pareto.csv"):
        assert (out / f).exists()
    pareto = pd.read_csv(out / "pareto.csv")
    t = res.table[res.table.source == "run"]
    expect = brute_force_front(t[["test_quadratic", "test_two"]].to_numpy(float), ["maximize", "minimize"],
                               (t.feasible & (t.status == "ok")).to_numpy())
    # Identical designs merged: the first trial of each distinct design, with its count.
    groups = {}
    for _, r in t[expect].sort_values("trial").iterrows():
        key = (round(r["link_length"], 12), round(r["slider_radius"], 12))
        groups.setdefault(key, []).append(int(r["trial"]))
    assert sorted(pareto["trial"]) == sorted(g[0] for g in groups.values())
    assert dict(zip(pareto["trial"], pareto["count"])) == {g[0]: len(g) for g in groups.values()}
    # columns as results.csv (units in the names, e.g. link_length_m) plus count
    assert list(pareto.columns) == list(pd.read_csv(res.out_dir / "results.csv").columns) + ["count"]
    assert "link_length_m" in pareto.columns and "test_two_m" in pareto.columns


def test_html_self_contained_and_tables_list_front(mo_run):
    """Images inline; the one file referenced is the shared plotly.js, by a relative path, present
    next to the report (the report directory is not in a folder named reports: its own assets/)."""
    study, res, out = mo_run
    text = (out / "index.html").read_text()
    p = _Collector()
    p.feed(text)
    assert len(p.imgs) >= 4
    assert all(src.startswith("data:image/png;base64,") for src in p.imgs), "an image is not embedded"
    assert len(p.links) == 1 and re.fullmatch(r"assets/plotly-\d+\.\d+\.\d+\.min\.js", p.links[0]), p.links
    script = out / p.links[0]
    assert script.stat().st_size > 1_000_000 and script.read_bytes()[:4000].count(b"plotly") > 0
    assert not re.search(r"https?://", text)
    pareto = pd.read_csv(out / "pareto.csv")
    # The non-dominated table: rows whose first cell is a trial number of the front.
    listed = set()
    section = text.split("<h2>Non-dominated designs</h2>")[1].split("<h2>")[0]
    q = _Collector()
    q.feed(section)
    for row in q.rows:
        if row:
            listed.add(int(float(row[0])))
    assert listed == set(pareto["trial"].astype(int))


def test_markdown_references_existing_images(mo_run):
    _, _, out = mo_run
    md = (out / "report.md").read_text()
    imgs = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md)
    assert imgs and all((out / i).exists() for i in imgs)
    paper = md.split("## The reference design")[1].split("## ")[0]
    assert re.search(r"(\d+ evaluated feasible designs? dominates? it|no evaluated feasible design dominates it)", paper)


def test_missing_and_empty_run_dirs(tmp_path):
    with pytest.raises(ReportError, match="does not exist"):
        write_report(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ReportError, match="no study.yaml"):
        write_report(tmp_path / "empty")


def test_interrupted_run_gives_partial_report(mo_run, tmp_path):
    study, res, out = mo_run
    src = res.out_dir
    dst = tmp_path / "cut"
    shutil.copytree(src, dst)
    lines = (dst / "journal.jsonl").read_text().splitlines()
    (dst / "journal.jsonl").write_text("\n".join(lines[:15]) + "\n" + lines[15][:40])  # a line cut by a kill
    rep = write_report(dst, out=tmp_path / "rep")
    html_text = (rep / "index.html").read_text()
    assert "Partial report" in html_text and "of 40 planned" in html_text
    # no journal at all: a clear message
    (dst / "journal.jsonl").unlink()
    with pytest.raises(ReportError, match="no evaluated designs"):
        write_report(dst, out=tmp_path / "rep2")


def test_cli_report_error_is_a_message_not_a_traceback(tmp_path):
    import sys

    r = subprocess.run([sys.executable, "-m", "parasynth.cli", "report", str(tmp_path / "missing")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "does not exist" in r.stderr and "Traceback" not in r.stderr


@pytest.fixture(scope="module")
def browser_paths():
    """Chromium and chromedriver (Debian's chromium, chromium-driver); a skip when missing, a
    failure with PARASYNTH_REQUIRE_BROWSER set."""
    return find_browser(BROWSER)


def test_page_renders_in_headless_chromium(mo_run, tmp_path, browser_paths):
    _, _, out = mo_run
    chromium = browser_paths[0]
    shot = tmp_path / "shot.png"
    cmd = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
           "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={tmp_path / 'u'}",
           "--window-size=1200,3000", f"--screenshot={shot}", (out / "index.html").resolve().as_uri()]
    subprocess.run(cmd, capture_output=True, timeout=120)
    assert shot.exists() and shot.stat().st_size > 20000
    import matplotlib.image as mpimg

    img = mpimg.imread(shot)[..., :3]
    # The plots are coloured (blue fronts, orange/red markers); text and tables are grey. A page
    # whose images failed to decode would be almost entirely grey.
    chroma = img.max(axis=-1) - img.min(axis=-1)
    assert (chroma > 0.25).mean() > 0.002
    dom = subprocess.run(cmd[:-2] + ["--dump-dom", (out / "index.html").resolve().as_uri()], capture_output=True,
                         text=True, timeout=120).stdout
    assert dom.count("<img") >= 4 and "Non-dominated designs" in dom


@pytest.fixture(scope="module")
def page(mo_run, browser_paths, tmp_path_factory):
    """The mo_run report open in headless Chromium driven by selenium through Debian's
    chromedriver (a Service with its path: nothing is downloaded); the browser's console log is
    kept."""
    webdriver = import_or_skip("selenium.webdriver", BROWSER, "selenium")
    from selenium.webdriver.chrome.service import Service

    chromium, driver_path = browser_paths
    opts = webdriver.ChromeOptions()
    opts.binary_location = chromium
    # WebGL (the 3D view) on the software renderer: no GPU in a headless test
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,1400",
                "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run",
                f"--user-data-dir={tmp_path_factory.mktemp('chromium')}"):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(executable_path=driver_path), options=opts)
    try:
        driver.set_page_load_timeout(60)
        driver.get((mo_run[2] / "index.html").resolve().as_uri())
        driver.set_script_timeout(30)
        _wait(driver, "return document.getElementById('viewer-3d').getAttribute('data-ready') === '1'")
        yield driver
    finally:
        driver.quit()


def _wait(driver, script, timeout=30.0):
    import time

    t0 = time.time()
    while time.time() - t0 < timeout:
        if driver.execute_script(script):
            return
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for: {script}")


_VIEW = "var g = document.getElementById('viewer-3d');"


def _state(driver) -> dict:
    """What the 3D view shows, read from the plotly graph div's data."""
    return driver.execute_script(_VIEW + """
        var byName = {}; g.data.forEach(function (t) { byName[t.name] = t; });
        return {names: g.data.map(function (t) { return t.name; }),
                legs: byName['actuated legs'].x.concat(byName['actuated legs'].z),
                centre: [byName['platform centre'].x[0], byName['platform centre'].y[0], byName['platform centre'].z[0]],
                anchors: byName['base anchors'].x.concat(byName['base anchors'].y),
                design: document.getElementById('viewer-design').value,
                pose: document.getElementById('viewer-pose').value,
                label: document.getElementById('viewer-pose-label').textContent,
                scene: !!(g._fullLayout && g._fullLayout.scene && g._fullLayout.scene._scene)};""")


def test_interactive_view_in_headless_chromium(page):
    """The 3D view is drawn, the pose slider moves the platform, a click on a front point of the
    objective plot switches the view to that design, and the console stays free of errors."""
    import io

    import matplotlib.image as mpimg
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    data = page.execute_script("return JSON.parse(document.getElementById('viewer-data').textContent)")
    s0 = _state(page)
    assert s0["scene"], "no 3D scene"
    assert {"actuated legs", "passive legs", "platform", "base anchors",
            "feasible workspace samples (platform centre)"} <= set(s0["names"])
    d0 = data["designs"][0]
    assert s0["design"] == "0" and d0["role"] == "recommended" and s0["centre"] == d0["C"][0]
    # drawn: the WebGL canvas of the view holds the actuated legs' blue (#1f77b4)
    view = page.find_element(By.ID, "viewer-3d")
    page.execute_script("arguments[0].scrollIntoView()", view)
    img = mpimg.imread(io.BytesIO(view.screenshot_as_png))[..., :3]
    blue = (np.abs(img - np.array([0x1F, 0x77, 0xB4]) / 255).max(axis=-1) < 0.08)
    assert blue.mean() > 0.001, f"the legs are not drawn ({blue.mean():.5f} of the pixels)"

    # the slider (keyboard on the range input): the platform moves to the next poses
    slider = page.find_element(By.ID, "viewer-pose")
    slider.click()
    slider.send_keys(Keys.HOME)
    slider.send_keys(Keys.RIGHT, Keys.RIGHT, Keys.RIGHT)
    s1 = _state(page)
    assert s1["pose"] == "3" and s1["centre"] == d0["C"][3] and s1["legs"] != s0["legs"]
    assert s1["label"].startswith("pose 4 of ") and d0["pose_text"][3] in s1["label"]

    # a click on a front point of another design: the viewer switches to it
    front = data["pareto"]["front"]["design"]
    j = next(j for j, d in enumerate(front) if d > 0 and data["designs"][d]["role"] == "front")
    target = front[j]
    point = page.execute_script("""
        var p = document.getElementById('viewer-pareto');
        var k = p.data.findIndex(function (t) { return t.name === 'non-dominated (click: view)'; });
        return p.querySelectorAll('.scatterlayer .trace')[k].querySelectorAll('path.point')[arguments[0]];""", j)
    page.execute_script("arguments[0].scrollIntoView({block: 'center'})", point)
    ActionChains(page).move_to_element(point).pause(0.2).click().perform()
    _wait(page, "return document.getElementById('viewer-design').value === arguments[0]".replace("arguments[0]", repr(str(target))))
    s2 = _state(page)
    dt = data["designs"][target]
    assert s2["anchors"] == [p[0] for p in dt["anchors"]] + [p[1] for p in dt["anchors"]]
    assert s2["centre"] == dt["C"][min(3, len(dt["C"]) - 1)]
    assert dt["name"] in page.find_element(By.ID, "viewer-design-info").text
    # the objective plot rings the design now in the viewer
    ring = page.execute_script("""var p = document.getElementById('viewer-pareto'); var t = p.data[p.data.length - 1];
                                  return [t.name, t.x, t.y];""")
    coords = data["pareto"]["front"]["coords"]
    assert ring == ["in the viewer", [coords[0][j]], [coords[1][j]]]
    # the pointer is on the point: its hover label shows the design values
    _wait(page, "return !!document.querySelector('#viewer-pareto .hoverlayer .hovertext')")
    hover = page.execute_script("return document.querySelector('#viewer-pareto .hoverlayer .hovertext').textContent")
    trial = int(data["designs"][target]["trial"])
    assert f"trial {trial}" in hover and "link_length = " in hover and "slider_radius = " in hover, hover

    # no error, and no warning of the page's own scripts (the browser's notes on its software
    # WebGL are of source "rendering")
    log = page.get_log("browser")
    errors = [e for e in log if e["level"] == "SEVERE" or e.get("source") in ("console-api", "javascript")]
    assert not errors, errors


def test_viewer_draws_the_mechanisms_own_joints(mo_run):
    """The viewer's legs are the inverse kinematics' joints: every 5-PUS/UPU rod (slider joint to
    platform anchor) keeps the design's link length at every pose, the platform is rigid, the
    first pose is home, and the switchable designs are bounded."""
    from parasynth.report.interactive import MAX_FRONT_DESIGNS, N_POSES, viewer_data
    from parasynth.study.rundir import design_mechanism

    study, res, out = mo_run
    run = load_run(res.out_dir)
    data = viewer_data(run, analyse(run))
    designs = data["designs"]
    assert [d["role"] for d in designs[:2]] == ["recommended", "reference"]
    assert 2 < len(designs) <= 2 + MAX_FRONT_DESIGNS
    for d in designs:
        values = {k: float(v.split()[0]) for k, v in d["values"]}  # mm
        A, B = np.array(d["A"]), np.array(d["B"])
        assert 1 < len(d["C"]) <= N_POSES and A.shape == B.shape == (len(d["C"]), 6, 3)
        rods = np.linalg.norm(A - B, axis=2)[:, np.array(d["actuated"])]
        assert rods.shape[1] == 5 and np.abs(rods - values["link_length"]).max() < 0.25
        gaps = np.linalg.norm(A[:, :, None] - A[:, None, :], axis=3)
        assert (gaps.max(axis=0) - gaps.min(axis=0)).max() < 0.3
    mech = design_mechanism(study, dict(study.reference))
    assert designs[1]["C"][0] == pytest.approx(list(mech.pose(mech.home)[0] * 1e3), abs=0.06)


def test_viewer_reads_the_drawings_the_run_stored(mo_run, monkeypatch, tmp_path):
    """The run's final stage stores the drawings (view.json) and the view reads them without
    sampling a workspace again; a run without view.json (an older version) is drawn again, and
    the view says so."""
    import shutil

    from parasynth.report import interactive
    from parasynth.study.rundir import design_mechanism, read_view, view_key

    study, res, out = mo_run
    stored = read_view(res.out_dir)
    assert stored is not None and "reference" in stored
    mech = design_mechanism(study, dict(study.reference))
    anchors = np.array([leg.base for leg in mech.legs]) * 1e3  # mm, from the design itself
    assert np.array(stored["reference"]["anchors"]) == pytest.approx(anchors, abs=0.06)

    def no_drawing(*a, **k):
        raise AssertionError("the view sampled a workspace again")

    run = load_run(res.out_dir)
    monkeypatch.setattr(interactive, "design_view", no_drawing)
    data = viewer_data_of(run)
    assert data["note"] == "" and len(data["designs"]) > 2
    assert data["designs"][1]["role"] == "reference" and view_key(study, None) in stored
    monkeypatch.undo()

    old = tmp_path / "old_run"
    shutil.copytree(res.out_dir, old)
    (old / "view.json").unlink()
    calls = []
    real = interactive.design_view
    monkeypatch.setattr(interactive, "design_view", lambda *a, **k: calls.append(1) or real(*a, **k))
    data_old = viewer_data_of(load_run(old))
    assert calls and "stored no drawings" in data_old["note"]
    assert [d["role"] for d in data_old["designs"]] == [d["role"] for d in data["designs"]]
    # the same design drawn again: the same anchors and home pose (the legs are the design's)
    assert data_old["designs"][1]["anchors"] == data["designs"][1]["anchors"]
    assert data_old["designs"][1]["C"][0] == pytest.approx(data["designs"][1]["C"][0], abs=0.06)


def viewer_data_of(run):
    from parasynth.report.interactive import viewer_data

    return viewer_data(run, analyse(run))


def test_ci_installs_and_requires_the_browser_and_the_dashboard():
    """.ci/run installs Chromium and its driver when missing and fails, not skips, the tests of
    optional tools; the test extra holds their Python packages; plotly is a dependency."""
    import tomllib

    root = Path(__file__).resolve().parents[2]
    ci = (root / ".ci" / "run").read_text()
    for var in ("PARASYNTH_REQUIRE_SIMULATORS", "PARASYNTH_REQUIRE_BROWSER", "PARASYNTH_REQUIRE_DASHBOARD"):
        assert f"export {var}=1" in ci
    assert "apt-get install -y -qq chromium chromium-driver" in ci
    project = tomllib.loads((root / "pyproject.toml").read_text())["project"]
    test = " ".join(project["optional-dependencies"]["test"])
    assert "selenium" in test and "optuna-dashboard" in test
    assert any(d.startswith("optuna-dashboard") for d in project["optional-dependencies"]["dashboard"])
    assert any(d.startswith("plotly") for d in project["dependencies"])


def test_reports_in_a_reports_folder_share_one_plotly_script(mo_run, tmp_path):
    """Reports inside a folder named reports reference ../assets/plotly-<version>.min.js, one copy."""
    _, res, _ = mo_run
    for name in ("a", "b"):
        write_report(res.out_dir, out=tmp_path / "reports" / name)
    scripts = list((tmp_path / "reports" / "assets").glob("plotly-*.min.js"))
    assert len(scripts) == 1 and not list((tmp_path / "reports").glob("*/assets"))
    for name in ("a", "b"):
        p = _Collector()
        p.feed((tmp_path / "reports" / name / "index.html").read_text())
        assert p.links == [f"../assets/{scripts[0].name}"]


# -- best designs, duplicates, verdicts within noise, display units, legibility ---------------------
from parasynth.measures.display import fmt_mean_se, fmt_number, fmt_quantity, quantity_unit  # noqa: E402
from parasynth.measures.objectives import OBJECTIVES, register  # noqa: E402
from parasynth.report.render import analyse, load_run, make_figures  # noqa: E402
from parasynth.study.evaluate import Record  # noqa: E402
from parasynth.study.final import best_designs  # noqa: E402
from parasynth.study.rundir import read_final  # noqa: E402

if "test_volume_m3" not in OBJECTIVES:
    @register("test_volume_m3", unit="m^3", sense="maximize", cost="cheap")
    def _test_volume_m3(mech):
        """L^2 R (m^3), a volume-like measure for the display tests."""
        return mech.params.link_length ** 2 * mech.params.slider_radius


def _mo_study():
    spec = {
        "name": "constructed", "mechanism": "5pus_upu",
        "variables": [{"name": "link_length", "low": "150 mm", "high": "250 mm"},
                      {"name": "slider_radius", "low": "100 mm", "high": "180 mm"}],
        "objectives": [{"name": "test_quadratic"}, {"name": "test_two"}],
        "reference": {"link_length": "205 mm", "slider_radius": "135 mm"},
        "evaluation": {"samples": 256},
        "optimizer": {"kind": "optuna", "algorithm": "nsga2", "n_trials": 6, "seed": 2},
    }
    return load_study(yaml.safe_dump(spec), is_text=True)


def _write_run(d: Path, study, records, final_rows=None) -> Path:
    """A run directory written by hand: study.yaml, journal.jsonl and optionally final.csv."""
    import json

    d.mkdir(parents=True)
    (d / "study.yaml").write_text(study.to_yaml())
    (d / "journal.jsonl").write_text("".join(json.dumps(r.to_dict()) + "\n" for r in records))
    if final_rows is not None:
        pd.DataFrame(final_rows).to_csv(d / "final.csv", index=False)
    return d


def _rec(trial, L, R, q, two, source="run"):
    return Record(values={"link_length": L, "slider_radius": R}, objectives={"test_quadratic": q, "test_two": two},
                  trial=trial, source=source, samples=256)


def test_best_designs_spread_and_duplicates_merged(tmp_path):
    study = _mo_study()
    # 12 distinct front designs (maximise q, minimise two: q increases with two), some evaluated
    # two or three times, plus dominated and infeasible ones.
    recs, trial = [], 0
    x = np.linspace(0.0, 1.0, 12) ** 2
    times = [1, 3, 1, 2, 1, 1, 2, 1, 1, 1, 3, 1]
    for i, (xi, c) in enumerate(zip(x, times)):
        for _ in range(c):
            recs.append(_rec(trial, 0.15 + 0.005 * i, 0.10 + 0.002 * i, -1 + xi, 0.4 + np.sqrt(xi)))
            trial += 1
    recs.append(_rec(trial, 0.2, 0.16, -1.0, 2.0))  # dominated
    trial += 1
    bad = _rec(trial, 0.21, 0.17, 5.0, 0.0)  # best on both, but failed
    bad.status = "failed"
    recs.append(bad)
    run_dir = _write_run(tmp_path / "run", study, recs)
    run = load_run(run_dir)
    runs = run.table[run.table.source == "run"]
    front = best_designs(study, runs, k=0)
    assert len(front) == 12 and sorted(front["count"]) == sorted(times)
    assert front["trial"].is_unique
    # spread: the designs a brute-force crowding truncation picks on the distinct front
    F = np.column_stack([-(-1 + x), 0.4 + np.sqrt(x)])
    pick = best_designs(study, runs, k=5)
    expect = brute_spread(F, 5)
    got = sorted(int(np.argmin(np.abs(x - (q + 1)))) for q in pick["test_quadratic"])
    assert got == sorted(expect)
    # the report's non-dominated table lists each design once, with its count
    out = write_report(run_dir, out=tmp_path / "rep")
    html_text = (out / "index.html").read_text()
    section = html_text.split("<h2>Non-dominated designs</h2>")[1].split("<h2>")[0]
    q = _Collector()
    q.feed(section)
    rows = [r for r in q.rows if r]
    assert len(rows) == 12
    assert sorted(int(r[1]) for r in rows) == sorted(times)  # the evaluations column
    assert "evaluated more than once" in section


def _final_row(source, trial, L, R, q, q_se, two, two_se, knee=False):
    return {"source": source, "trial": trial, "link_length": L, "slider_radius": R, "test_quadratic": q,
            "test_quadratic_stderr": q_se, "test_two": two, "test_two_stderr": two_se, "feasible": True,
            "samples": 4096, "repeats": 4, "knee": knee, "count": 1}


def test_verdict_uses_reevaluated_values_and_says_within_noise(tmp_path):
    study = _mo_study()
    # Single samples: design A (trial 0) dominates the paper's design by 1 % on test_two and
    # slightly on test_quadratic; B (trial 1) is a trade-off.
    recs = [_rec(-1, 0.205, 0.135, -0.00110, 0.5050, source="reference"),
            _rec(0, 0.200, 0.132, -0.00100, 0.5000),
            _rec(1, 0.190, 0.120, -0.01000, 0.4300)]
    single = _write_run(tmp_path / "single", study, recs)
    txt = (write_report(single, out=tmp_path / "r0") / "report.md").read_text()
    paper = txt.split("## The reference design")[1].split("## ")[0]
    assert "1 evaluated feasible design dominates it" in paper and "not re-evaluated" in paper
    # Re-evaluated: the differences between A and the paper's design are within 2 standard errors
    # (test_two: 0.504 vs 0.506, combined s.e. 0.0028; test_quadratic: -0.00105 vs -0.00108).
    fin = [_final_row("best", 0, 0.200, 0.132, -0.00105, 0.00010, 0.5040, 0.0020, knee=True),
           _final_row("best", 1, 0.190, 0.120, -0.01000, 0.00010, 0.4300, 0.0020),
           _final_row("reference", -1, 0.205, 0.135, -0.00108, 0.00010, 0.5060, 0.0020)]
    noisy = _write_run(tmp_path / "noisy", study, recs, fin)
    txt = (write_report(noisy, out=tmp_path / "r1") / "report.md").read_text()
    paper = txt.split("## The reference design")[1].split("## ")[0]
    assert "none of the 2 re-evaluated designs dominates it beyond noise" in paper
    assert "Equal to it within noise on every objective: trial 0" in paper
    assert "1 evaluated feasible design dominates it; the re-evaluation above decides" in paper
    # The same differences with ten times smaller standard errors are real: A dominates.
    fin2 = [dict(r, test_quadratic_stderr=r["test_quadratic_stderr"] / 10, test_two_stderr=r["test_two_stderr"] / 10)
            for r in fin]
    sharp = _write_run(tmp_path / "sharp", study, recs, fin2)
    txt = (write_report(sharp, out=tmp_path / "r2") / "report.md").read_text()
    paper = txt.split("## The reference design")[1].split("## ")[0]
    assert "1 of the 2 re-evaluated designs dominates it" in paper
    # test_quadratic: -0.00105 vs -0.00108 with s.e. 1e-5 each: 3e-5 < 2 * 1.41e-5 * ... is 2.1 s.e.
    assert "better on test_quadratic" in paper and "test_two" in paper.split("better on")[1]
    # the knee is shown re-evaluated
    assert "re-evaluated: test_quadratic = " in txt


def test_knee_is_always_reevaluated(mo_run):
    study, res, out = mo_run
    fin = read_final(study, res.out_dir / "final.csv") if (res.out_dir / "final.csv").exists() else None
    if fin is None:  # the fixture study has no final re-evaluation: do it here
        from parasynth.study import Evaluator
        from parasynth.study.final import reevaluate_best

        s2 = load_study(yaml.safe_dump({**yaml.safe_load(study.to_yaml()),
                                        "evaluation": {"samples": 256, "final_samples": 256, "final_repeats": 2,
                                                       "final_top": 2}}), is_text=True)
        fin = reevaluate_best(s2, Evaluator(s2), res.table, res.out_dir)
    a = analyse(load_run(res.out_dir))
    knee = a.knee_row
    best = fin[fin.source == "best"]
    hit = best[np.isclose(best.link_length, knee.link_length) & np.isclose(best.slider_radius, knee.slider_radius)]
    assert len(hit) == 1 and bool(hit["knee"].iloc[0])
    assert int(best["knee"].sum()) == 1


def test_display_units_without_float_noise():
    assert fmt_quantity(0.20500000000000002, "length") == "205 mm"
    assert fmt_quantity(0.1 + 0.2, "length") == "300 mm"
    assert fmt_quantity(np.deg2rad(15), "angle") == "15 deg"
    assert fmt_number(205.00000000000003) == "205" and fmt_number(0.1 + 0.2) == "0.3"
    assert fmt_number(1.23456789e-7) == "1.235e-7" and fmt_number(True) == "True"
    study = load_study("studies/5pus_upu_link_length.yaml")
    vol = quantity_unit(study, "volume")  # workspace volume over three position coordinates, m^3
    assert vol.symbol == "cm^3" and fmt_quantity(0.0026184, vol) == "2618 cm^3"
    assert quantity_unit(study, "x_size").symbol == "mm" and quantity_unit(study, "isotropy").symbol == ""
    assert quantity_unit(study, "link_length").label("link_length") == "link_length [mm]"
    # two significant digits of the standard error, the mean to the same place
    assert fmt_mean_se(0.19167, 0.0013628, quantity_unit(study, "z_range")) == "191.7 ± 1.4"
    assert fmt_mean_se(0.0025932, 6.1359e-06, vol) == "2593.2 ± 6.1"


def test_run_summary_in_display_units(mo_run):
    study, res, _ = mo_run
    text = run_summary(study, res)
    assert "link_length [mm]" in text and "'" not in text.splitlines()[0]
    # no float noise: no number with more than 6 significant digits
    for num in re.findall(r"\d+\.\d+", text):
        assert len(num.replace(".", "").lstrip("0")) <= 6, num


def test_html_tables_scroll_inside_the_page(mo_run):
    _, _, out = mo_run
    text = (out / "index.html").read_text()
    assert re.search(r"\.table-wrap\{[^}]*overflow-x:\s*auto", text)
    n_tables = text.count("<table")
    assert n_tables >= 2
    assert len(re.findall(r"<div class='table-wrap'>\s*<table", text)) == n_tables


def _text_boxes_overlap(fig):
    """Pairs of overlapping tick labels (same axis), tick or axis labels of different panels
    that overlap, and labels of a panel that run into another panel's plotting area, in the
    drawn figure."""
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    bad, per_axes = [], []
    for ax in fig.axes:
        if not ax.get_visible() or not ax.axison or ax.name != "rectilinear":
            continue
        boxes = []
        for axis in (ax.xaxis, ax.yaxis):
            lo, hi = sorted(axis.get_view_interval())
            tol = 1e-9 * max(1.0, abs(hi - lo))
            labs = [t.label1 for t in axis.get_major_ticks()  # the ticks drawn: inside the view
                    if lo - tol <= t.get_loc() <= hi + tol and t.label1.get_visible() and t.label1.get_text().strip()]
            bb = [t.get_window_extent(r).expanded(0.98, 0.98) for t in labs]
            for i, j in itertools.combinations(range(len(bb)), 2):
                if bb[i].overlaps(bb[j]):
                    bad.append((labs[i].get_text(), labs[j].get_text()))
            boxes += bb
            if axis.label.get_text():
                boxes.append(axis.label.get_window_extent(r).expanded(0.98, 0.98))
        per_axes.append((boxes, ax.bbox))
    for (A, frame_a), (B, frame_b) in itertools.combinations(per_axes, 2):
        if any(a.overlaps(b) for a in A for b in B):
            bad.append("labels of two panels overlap")
        if any(a.overlaps(frame_b) for a in A) or any(b.overlaps(frame_a) for b in B):
            bad.append("labels of a panel run into another panel")
    return bad


def test_figure_tick_labels_do_not_overlap(tmp_path, mo_run):
    # A six-objective sweep with volumes in m^3 (shown in cm^3) and lengths in m (shown in mm).
    spec = {
        "name": "six", "mechanism": "5pus_upu",
        "variables": [{"name": "link_length", "values": [f"{v} mm" for v in (150, 170, 190, 210, 230, 250)]}],
        "fixed": {"slider_radius": "135 mm"},
        "objectives": [{"name": "test_volume_m3", "label": f"vol{k}"} for k in range(3)]
        + [{"name": "test_two", "label": "two"}, {"name": "test_link_length", "label": "length", "goal": "maximize"},
           {"name": "test_quadratic", "label": "quad"}],
        "reference": {"link_length": "210 mm"},
        "evaluation": {"samples": 256, "final_samples": 256, "final_repeats": 2},
        "optimizer": {"kind": "sweep"},
    }
    study = load_study(yaml.safe_dump(spec), is_text=True)
    res = run_study(study, out_dir=tmp_path / "run", progress=False)
    for run_dir in (res.out_dir, mo_run[1].out_dir):
        run = load_run(run_dir)
        figs = make_figures(run, analyse(run), keep=True)
        assert {"pareto", "parallel", "convergence"} <= set(figs.figures)
        for name, fig in figs.figures.items():
            assert _text_boxes_overlap(fig) == [], name
    sweep = make_figures(load_run(res.out_dir), analyse(load_run(res.out_dir)), keep=True).figures["sweep"]
    panels = [ax for ax in sweep.axes if ax.axison]
    assert len(panels) == 6
    # a grid that wraps: at most three panels in a row
    rows = {round(ax.get_position().y0, 3) for ax in panels}
    assert len(rows) == 2
    labels = [ax.get_ylabel() for ax in panels]
    assert "vol0 [cm^3]" in labels and "two [mm]" in labels
    # tick labels are plain numbers of a few digits (no 0.0025000, no offset text)
    for ax in panels:
        for t in ax.get_yticklabels():
            assert len(t.get_text().replace("\u2212", "-")) <= 7, t.get_text()
        assert ax.yaxis.get_offset_text().get_text() == ""


def test_overlap_check_detects_crowded_panels():
    """The check above finds the faults it is meant to find: six panels squeezed into one row
    with many ticks of long SI numbers (m^3) overlap."""
    from matplotlib.ticker import MaxNLocator

    from parasynth.report.figures import _subplots

    fig, axes = _subplots(1, 6, figsize=(6, 2), layout=None)
    for ax in axes:
        ax.plot([0.0013943, 0.0032822], [0.0013943, 0.0032822])
        ax.xaxis.set_major_locator(MaxNLocator(nbins=20))
        ax.ticklabel_format(useOffset=False, style="plain")
    bad = _text_boxes_overlap(fig)
    assert bad and "labels of two panels overlap" in bad and any(isinstance(b, tuple) for b in bad)


def test_stale_final_without_the_knee_is_said(tmp_path):
    study = _mo_study()
    recs = [_rec(-1, 0.205, 0.135, -0.00110, 0.5050, source="reference"),
            _rec(0, 0.200, 0.132, -0.00100, 0.5000),
            _rec(1, 0.190, 0.120, -0.01000, 0.4300),
            _rec(2, 0.180, 0.110, -0.00500, 0.4600)]
    run = load_run(_write_run(tmp_path / "probe", study, recs))
    knee = analyse(run).knee_row
    others = [r for r in recs[1:] if r.trial != int(knee["trial"])]
    # final.csv written before the knee design existed: it holds the other designs only
    fin = [_final_row("best", r.trial, r.values["link_length"], r.values["slider_radius"], r.objectives["test_quadratic"],
                      1e-5, r.objectives["test_two"], 1e-3, knee=(k == 0)) for k, r in enumerate(others)]
    fin.append(_final_row("reference", -1, 0.205, 0.135, -0.0011, 1e-5, 0.505, 1e-3))
    txt = (write_report(_write_run(tmp_path / "stale", study, recs, fin), out=tmp_path / "rep") / "report.md").read_text()
    assert "final.csv does not hold this design" in txt
    assert "| recommended (knee) |" not in txt and re.search(r"\| best test_(quadratic|two) \|", txt)


class _PatternEvaluator:
    """Stands in for the Evaluator in the final re-evaluation: each design's objectives are
    its given true values plus ``sigma`` times the pattern +1, -1, +1, -1 over the repeats, so
    the re-evaluated mean is the true value and the standard error is known in closed form
    (sigma * sqrt(4/3) / 2 for four repeats)."""

    def __init__(self, truth: dict, sigma: float, base_seed: int):
        self.truth, self.sigma, self.base = truth, sigma, base_seed

    def evaluate(self, values, n, seed):
        from types import SimpleNamespace

        key = (round(float(values["link_length"]), 9), round(float(values["slider_radius"]), 9))
        q, two = self.truth[key]
        s = self.sigma * (1.0 if (seed - self.base) % 2 == 0 else -1.0)
        return SimpleNamespace(objectives={"test_quadratic": q + s, "test_two": two + s}, feasible=True, status="ok",
                               constraint_values={}, robust={}, seed=seed, samples=n)


@pytest.fixture
def noisy_test_objectives(monkeypatch):
    """The analytic test objectives stand in for sampled ones (a statistic over seeds): without it
    they are exact and the final stage keeps their run values."""
    import dataclasses

    from parasynth.measures.objectives import OBJECTIVES
    for name in ("test_quadratic", "test_two"):
        monkeypatch.setitem(OBJECTIVES, name, dataclasses.replace(OBJECTIVES[name], estimate="statistic",
                                                                  sample=True))


def _screen_case():
    """A run whose front is a line q = -1 + x (maximise), two = 0.4 + x (minimise), x = i / 8,
    and a paper design just behind its middle (q = -0.55, two = 0.95). Single-sample
    dominators of the paper's design: the front's middle design (gains 0.05, 0.05) and three
    designs off the front (gains 0.03/0.02, 0.01/0.01, 0.04/0.001, all dominated by it)."""
    spec = yaml.safe_load(_mo_study().to_yaml())
    spec["evaluation"] = {"samples": 256, "final_samples": 512, "final_repeats": 4, "final_top": 3}
    study = load_study(yaml.safe_dump(spec), is_text=True)
    recs, truth = [], {}

    def add(trial, L, R, q, two, source="run"):
        recs.append(_rec(trial, L, R, q, two, source=source))
        truth[(round(L, 9), round(R, 9))] = (q, two)

    add(-1, 0.205, 0.135, -0.55, 0.95, source="reference")
    for i in range(9):
        add(i, 0.150 + 0.01 * i, 0.100 + 0.005 * i, -1 + i / 8, 0.4 + i / 8)
    add(20, 0.231, 0.171, -0.52, 0.93)    # least gain 0.02
    add(21, 0.232, 0.172, -0.54, 0.94)    # least gain 0.01
    add(22, 0.233, 0.173, -0.51, 0.949)   # least gain 0.001: fourth, not re-evaluated
    add(23, 0.234, 0.174, -0.60, 0.90)    # trade-off with the paper's design, not a dominator
    return study, recs, truth


def test_screening_dominators_ordered_by_normalised_margin(tmp_path):
    from parasynth.study.final import final_candidates, screening_dominators

    study, recs, _ = _screen_case()
    table = load_run(_write_run(tmp_path / "run", study, recs)).table
    scr = screening_dominators(study, table)
    # by hand: least normalised gain (both ranges are 1 over the feasible designs)
    assert [int(t) for t in scr["trial"]] == [4, 20, 21, 22]
    assert np.allclose(scr["screen_margin"], [0.05, 0.02, 0.01, 0.001])
    cand = final_candidates(study, table)
    trials = [int(t) for t in cand["trial"]]
    # the crowding spread of the front (3 designs) does not hold the off-front dominators
    assert 20 not in trials[:3] and 21 not in trials[:3]
    # the three by the largest margin are candidates, the fourth is not
    assert {4, 20, 21} <= set(trials) and 22 not in trials and 23 not in trials
    flag = dict(zip(trials, cand["dominates_reference_screen"]))
    assert flag[4] and flag[20] and flag[21] and not flag[0] and not flag[8]
    role = dict(zip(trials, cand["role"]))
    assert role[20] == role[21] == "screen"
    assert len(set(trials)) == len(trials)


@pytest.mark.parametrize("sigma", [1e-4, 1.0])
def test_verdict_decides_on_the_screening_dominators(tmp_path, sigma, noisy_test_objectives):
    from parasynth.study.final import reevaluate_best

    study, recs, truth = _screen_case()
    run_dir = _write_run(tmp_path / "run", study, recs)
    table = load_run(run_dir).table
    fin = reevaluate_best(study, _PatternEvaluator(truth, sigma, study.evaluation["seed"] + 1000), table, run_dir)
    best = fin[fin.source == "best"]
    assert {4, 20, 21} <= set(best.trial[best.dominates_reference_screen].astype(int))
    assert set(fin.role) >= {"screen", "reference"}
    # closed-form standard error of the pattern
    assert np.allclose(best["test_two_stderr"], sigma * np.sqrt(4 / 3) / 2)
    txt = (write_report(run_dir, out=tmp_path / "rep") / "report.md").read_text()
    paper = txt.split("## The reference design")[1].split("## ")[0]
    assert "Screening dominators re-evaluated: 3 of the 4 distinct ones (the ones by the largest normalised margin)" in paper
    if sigma < 0.01:
        # gains of 0.01 and more against a combined standard error of 8e-5: all three dominate
        assert "3 of them dominate it beyond noise (trial 4, trial 20, trial 21)" in paper
        assert "trial 22" not in paper
    else:
        # gains of at most 0.05 against 2 x 0.82 combined standard errors: all within noise
        assert "none of them dominates it beyond noise: all of them are equal to it within noise" in paper
        assert "none of the" in paper and "re-evaluated designs dominates it beyond noise" in paper
    # the re-evaluation table marks them
    sec = txt.split("## Re-evaluation of the best designs")[1]
    assert sec.count("dominates reference design (screening)") >= 2


# -- the templates state the analysis: content checked without the templating ---------------------
class _Doc(HTMLParser):
    """Section titles, paragraph text and tables (header, rows) of the HTML report."""

    def __init__(self):
        super().__init__()
        self.sections, self._tag, self._cell, self._table = [], None, None, None

    def handle_starttag(self, tag, attrs):
        if tag == "h2":
            self.sections.append({"title": "", "text": "", "tables": []})
        self._tag = tag if tag in ("h2", "p", "b") or self._tag not in ("p", "b") else self._tag
        if tag == "table" and self.sections:
            self._table = {"head": [], "rows": []}
            self.sections[-1]["tables"].append(self._table)
        if tag == "tr" and self._table is not None:
            self._table["rows"].append([])
        if tag in ("th", "td"):
            self._cell = ""
        if tag == "p" and self.sections:
            self.sections[-1]["text"] += " "

    def handle_endtag(self, tag):
        if tag in ("th", "td") and self._table is not None:
            (self._table["head"] if tag == "th" else self._table["rows"][-1]).append(self._cell)
            self._cell = None
        if tag == "table":
            self._table = None
        if tag in ("h2", "p"):
            self._tag = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data
        elif self._tag == "h2":
            self.sections[-1]["title"] += data
        elif self._tag in ("p", "b") and self.sections:
            self.sections[-1]["text"] += data


def _md_sections(md: str) -> list[dict]:
    out = []
    for block in md.split("\n## ")[1:]:
        title, _, body = block.partition("\n")
        lines = [ln for ln in body.splitlines() if ln.startswith("| ")]
        head = [c.strip() for c in lines[0].strip("|").split("|")] if lines else []
        rows = [[c.strip() for c in ln.strip("|").split("|")] for ln in lines[1:]]
        text = " ".join(ln for ln in body.split("```")[0].splitlines() if ln and not ln.startswith(("|", "!", "*")))
        out.append({"title": title.strip(), "text": text, "tables": [{"head": head, "rows": rows}] if lines else []})
    return out


def _words(s: str) -> str:
    return " ".join(s.replace("**", "").split())


def test_html_and_markdown_state_the_same_sections_and_the_run_values(mo_run):
    study, res, out = mo_run
    doc = _Doc()
    doc.feed((out / "index.html").read_text())
    md = _md_sections((out / "report.md").read_text())
    titles = [s["title"] for s in doc.sections]
    assert titles == [s["title"] for s in md]
    assert titles[:2] == ["Recommendation", "Summary"] and titles[-1] == "Study and software" and titles[-2] == "Figures"
    for h, m in zip(doc.sections, md):
        if h["title"] != "Figures":  # the same sentences, bold markup aside
            assert _words(h["text"]) == _words(m["text"]), h["title"]
        assert [(t["head"], [[c.strip() for c in r] for r in t["rows"] if r]) for t in h["tables"]] == \
            [(t["head"], t["rows"]) for t in m["tables"]], h["title"]
    # The non-dominated table holds pareto.csv's designs in display units (mm for lengths,
    # cm^2 for test_quadratic in m^2), four significant digits.
    table = next(s for s in doc.sections if s["title"] == "Non-dominated designs")["tables"][0]
    head = table["head"]
    assert head[:2] == ["trial", "evaluations"] and "link_length [mm]" in head and "test_two [mm]" in head
    assert "test_quadratic [cm^2]" in head and head[-1] == "feasible"
    pareto = pd.read_csv(out / "pareto.csv").set_index("trial")
    rows = [r for r in table["rows"] if r]
    assert sorted(int(r[0]) for r in rows) == sorted(pareto.index)
    for r in rows:
        cell = dict(zip(head, r))
        p = pareto.loc[int(cell["trial"])]
        assert int(cell["evaluations"]) == p["count"]
        for col, si, factor in (("link_length [mm]", "link_length_m", 1e3), ("slider_radius [mm]", "slider_radius_m", 1e3),
                                ("test_two [mm]", "test_two_m", 1e3), ("test_quadratic [cm^2]", "test_quadratic_m2", 1e4)):
            assert float(cell[col]) == pytest.approx(p[si] * factor, rel=5e-4, abs=1e-9), (col, cell[col], p[si])
        assert cell["feasible"] == "yes"
    # the reference design's row: the values of the study's reference (205 mm, 135 mm)
    ref = next(s for s in doc.sections if s["title"] == "The reference design")["tables"][0]
    cell = dict(zip(ref["head"], [r for r in ref["rows"] if r][0]))
    assert cell["link_length [mm]"] == "205" and cell["slider_radius [mm]"] == "135"
    # the summary counts are the run's
    runs = res.table[res.table.source == "run"]
    n_feas = int((runs.feasible.astype(bool) & (runs.status == "ok")).sum())
    assert f"{len(runs)} designs evaluated" in doc.sections[1]["text"] and f"{n_feas} feasible" in doc.sections[1]["text"]


def test_html_report_escapes_the_study_text(tmp_path):
    spec = yaml.safe_load(_mo_study().to_yaml())
    spec["description"] = "Tags <script>alert(1)</script> & <b>bold</b> are text; **this** is bold."
    spec["reference"]["label"] = "the </script><script>alert(2)</script> design"  # also in the viewer's data
    study = load_study(yaml.safe_dump(spec), is_text=True)
    recs = [_rec(0, 0.200, 0.132, -0.001, 0.50), _rec(1, 0.190, 0.120, -0.01, 0.43)]
    out = write_report(_write_run(tmp_path / "run", study, recs), out=tmp_path / "rep")
    text = (out / "index.html").read_text()
    # the page's own scripts (plotly.js, the viewer's data and code) and no other
    assert text.count("<script") == 3 and "<script>alert" not in text
    assert "alert(2)" in text and "</script><script>alert(2)" not in text
    assert "&lt;script&gt;alert(1)&lt;/script&gt; &amp; &lt;b&gt;bold&lt;/b&gt;" in text
    assert "<b>this</b> is bold" in text
    assert "Tags <script>alert(1)</script> & <b>bold</b> are text; **this** is bold." in (out / "report.md").read_text()


def test_a_run_without_a_feasible_design_or_reference_still_reports(tmp_path):
    """Nothing feasible and no reference design: final.csv holds its header alone (it was an
    empty file the report refused as damaged), and the report says nothing is recommended."""
    d = {"name": "nofeas", "mechanism": "5pus_upu",
         "variables": [{"name": "link_length", "low": "150 mm", "high": "250 mm"}],
         "objectives": [{"name": "test_quadratic", "goal": "maximize"}],
         # test_link_length is the link length itself: at most 250 mm here, never 1 m
         "constraints": [{"name": "test_link_length", "label": "L", "min": "1 m"}],
         "evaluation": {"samples": 64}, "optimizer": {"kind": "optuna", "algorithm": "random", "n_trials": 6, "seed": 1}}
    res = run_study(load_study(yaml.safe_dump(d), is_text=True), out_dir=tmp_path / "r", progress=False)
    assert not res.table["feasible"].astype(bool).any()
    final = pd.read_csv(tmp_path / "r" / "final.csv")
    assert len(final) == 0 and "source" in final.columns
    md = (write_report(tmp_path / "r", tmp_path / "rep") / "report.md").read_text()
    assert "**No feasible design was found**: nothing is recommended." in md
    assert "| L | test_link_length | min 1000 mm | 6 |" in md
