"""Pareto analysis against brute force and known values; the report files."""

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

from parasynth.cli import load_plugins
from parasynth.report import (ReportError, hypervolume, knee_index, non_dominated_ranks, pareto_mask,
                              reference_standing, to_min, write_report)
from parasynth.study import load_study, run_study

PLUGIN = str(Path(__file__).parent / "data" / "analytic_plugin.py")
load_plugins(PLUGIN)


def brute_force_front(F, senses, feasible):
    """Non-dominated feasible set by the definition, pair by pair."""
    sign = np.array([1 if s == "minimize" else -1 for s in senses])
    G = F * sign
    out = []
    for i in range(len(G)):
        if not feasible[i]:
            continue
        dominated = False
        for j in range(len(G)):
            if j != i and feasible[j] and all(G[j] <= G[i]) and any(G[j] < G[i]):
                dominated = True
                break
        out.append(not dominated)
    mask = np.zeros(len(G), bool)
    mask[np.flatnonzero(feasible)] = out
    return mask


@pytest.mark.parametrize("seed", range(8))
def test_pareto_mask_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    n, m = 60, 2 + seed % 3
    F = rng.integers(0, 6, size=(n, m)).astype(float)  # ties on purpose
    senses = [("minimize", "maximize")[k % 2] for k in range(m)]
    feas = rng.random(n) > 0.3
    np.testing.assert_array_equal(pareto_mask(F, senses, feas), brute_force_front(F, senses, feas))


def test_constraint_domination_ranks():
    F = np.array([[1, 5], [2, 3], [3, 4], [4, 1], [5, 5]], float)
    v = np.array([0, 0, 0, 1.0, 0.5])
    r = non_dominated_ranks(F, v)
    # feasible fronts first ({0, 1}, then {2}); infeasible by violation (4: 0.5, then 3: 1.0)
    assert list(r) == [0, 0, 1, 3, 2]
    # no infeasible design ever ranks before a feasible one
    assert r[v > 0].min() > r[v == 0].max()


def test_hypervolume_known_values():
    assert hypervolume(np.array([[1.0, 5], [2, 3], [4, 1]]), [6, 6]) == pytest.approx(17.0)
    # one point: a box
    assert hypervolume(np.array([[1.0, 2, 3]]), [2, 4, 7]) == pytest.approx(1 * 2 * 4)
    # two boxes in 3-D with a known overlap: [0,2]x[0,1]x[0,1] and [0,1]x[0,2]x[0,1] from ref 2,2,1
    P = np.array([[0.0, 1, 0], [1, 0, 0]])
    assert hypervolume(P, [2, 2, 1]) == pytest.approx(2 + 2 - 1)
    # points not better than the reference contribute nothing
    assert hypervolume(np.array([[3.0, 3]]), [2, 2]) == 0.0


def test_hypervolume_against_monte_carlo():
    rng = np.random.default_rng(0)
    P = rng.random((12, 3))
    ref = np.ones(3) * 1.1
    exact = hypervolume(P, ref)
    S = rng.random((400_000, 3)) * 1.1
    dominated = np.zeros(len(S), bool)
    for p in P:
        dominated |= np.all(S >= p, axis=1)
    mc = dominated.mean() * 1.1**3
    assert exact == pytest.approx(mc, rel=0.01)


def test_knee_of_a_convex_front():
    x = np.linspace(0, 1, 21)
    F = np.column_stack([x, (1 - np.sqrt(x)) ** 2])  # symmetric about x = y, knee at x = 0.25
    k = knee_index(F)
    assert F[k, 0] == pytest.approx(0.25, abs=0.051)


def test_reference_standing_counts_dominators():
    F = np.array([[1.0, 1], [2, 2], [0.5, 3], [3, 0.5]])
    st = reference_standing(F, ["minimize", "minimize"], np.ones(4, bool), np.array([2.5, 2.5]), ["a", "b"])
    assert st.n_dominating == 2 and set(st.dominating_indices) == {0, 1}
    assert st.best_improvements["a"] == pytest.approx((2.5 - 1) / 2.5)


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
    assert sorted(pareto["trial"]) == sorted(t[expect]["trial"])
    assert list(pareto.columns) == list(res.table.columns)


def test_html_self_contained_and_tables_list_front(mo_run):
    study, res, out = mo_run
    text = (out / "index.html").read_text()
    p = _Collector()
    p.feed(text)
    assert len(p.imgs) >= 4
    assert all(src.startswith("data:image/png;base64,") for src in p.imgs), "an image is not embedded"
    assert not p.links, "external resources referenced"
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
    assert "Paper design" in md and "dominated by" in md or "No evaluated feasible design dominates" in md


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


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")


@pytest.mark.skipif(CHROMIUM is None, reason="headless Chromium is not installed (apt-get install chromium)")
def test_page_renders_in_headless_chromium(mo_run, tmp_path):
    _, _, out = mo_run
    shot = tmp_path / "shot.png"
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
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
