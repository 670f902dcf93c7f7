"""Study reports: ``index.html`` (images inline, and the interactive view of
:mod:`.interactive`, which loads plotly.js from a shared ``assets/`` folder), ``report.md``
(images in ``img/``) and ``pareto.csv`` (the non-dominated feasible designs, columns as
results.csv).

``write_report(run_dir, out=None)`` reads a run directory through
:mod:`parasynth.study.rundir` (``study.yaml``, ``results.csv`` or the journal,
``final.csv``), analyses it (:mod:`.analysis`), draws the figures (:mod:`.figures`), states
the sections (:mod:`.sections`) and renders them with the Jinja2 templates
``templates/report.html`` (autoescaped) and ``templates/report.md``. A missing or empty run
directory raises :class:`ReportError` with a clear message; an interrupted run gives a
report marked *partial*.
"""

from __future__ import annotations

import base64
import re
from functools import lru_cache
from pathlib import Path

import jinja2
from markupsafe import Markup, escape

from ..study.rundir import Run, RunDirError, read_run, to_csv_columns
from .analysis import NOISE_Z, Analysis, analyse
from .figures import Figures, make_figures
from .interactive import plotly_script, viewer_data, viewer_json, viewer_script
from .robust import robust_sections
from .sections import Section, Table, sections
from .structures import plot_structures, structure_sections
from .tables import display_table, final_display_table

__all__ = ["write_report", "ReportError", "load_run", "render_html", "render_markdown", "analyse", "make_figures",
           "display_table", "final_display_table", "Analysis", "NOISE_Z", "default_report_dir", "REPORT_SUBDIR"]


class ReportError(ValueError):
    """The run directory cannot be reported (missing, empty, unreadable)."""


def load_run(run_dir) -> Run:
    """The run directory read (:func:`parasynth.study.rundir.read_run`); :class:`ReportError`
    when there is no run to report."""
    try:
        return read_run(run_dir)
    except RunDirError as e:
        raise ReportError(str(e)) from None


def _inline(text: str) -> Markup:
    """Report text as HTML: escaped, ``**bold**`` as <b>, blank lines as paragraph breaks."""
    s = str(escape(text))
    return Markup(re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", s).replace("\n\n", "</p><p>"))


@lru_cache(maxsize=1)
def _env() -> jinja2.Environment:
    env = jinja2.Environment(loader=jinja2.PackageLoader("parasynth.report", "templates"),
                             autoescape=jinja2.select_autoescape(["html"], default_for_string=False),
                             undefined=jinja2.StrictUndefined, keep_trailing_newline=False)
    env.filters["inline"] = _inline
    return env


def _figures(figs: Figures, html: bool) -> list[dict]:
    out = []
    for name, caption, png in figs.items:
        src = None
        if png:
            src = f"data:image/png;base64,{base64.b64encode(png).decode()}" if html else f"img/{name}.png"
        out.append({"name": name, "caption": caption, "src": src})
    return out


def render_html(run: Run, secs: list[Section], figs: Figures, viewer: dict | None = None,
                script: str | None = None) -> str:
    """index.html: the sections, the figures inline (before the last section), preceded by the
    interactive view when ``viewer`` (:func:`.interactive.viewer_data`) and ``script`` (the
    path of plotly.js relative to the page) are given."""
    view = None
    if viewer is not None and script is not None:
        sources = {d["pose_source"] for d in viewer["designs"]}
        view = {"script": script, "data": viewer_json(viewer), "code": viewer_script(),
                "n_designs": len(viewer["designs"]), "note": viewer.get("note", ""),
                "pose_source": sources.pop() if len(sources) == 1 else "poses of each design"}
    return _env().get_template("report.html").render(
        name=run.study.name, partial=run.partial_reason if run.partial else None, sections=secs,
        figures=_figures(figs, html=True), viewer=view)


def render_markdown(run: Run, secs: list[Section], figs: Figures, interactive: bool = False) -> str:
    """report.md: the sections, the figures as links to img/<name>.png (and, with
    ``interactive``, a line saying that index.html has the interactive view)."""
    text = _env().get_template("report.md").render(name=run.study.name, sections=secs,
                                                   figures=_figures(figs, html=False), interactive=interactive)
    return text.rstrip("\n") + "\n"


#: The report's folder inside its run directory when no other is given.
REPORT_SUBDIR = "report"


def default_report_dir(run_dir) -> Path:
    """Where the report of ``run_dir`` goes unless told otherwise: ``<run_dir>/report/``."""
    return Path(run_dir) / REPORT_SUBDIR


def write_report(run_dir, out=None, noise_z: float = NOISE_Z, assets=None) -> Path:
    """Write index.html, report.md and pareto.csv for a run directory; returns the report dir,
    ``out`` or by default ``<run_dir>/report/`` (:func:`default_report_dir`: the report goes with
    its run; ``parasynth run-all`` writes the committed ``reports/<study name>/``).

    ``pareto.csv``: the distinct non-dominated feasible designs, columns as results.csv plus
    ``count`` (how many times the design was evaluated). ``noise_z``: a difference between
    re-evaluated designs counts when it exceeds this many combined standard errors.
    ``assets``: the folder of the scripts reports share (plotly.js); by default
    ``<reports>/assets`` for a report in a folder named ``reports``, else ``<out>/assets``
    (:func:`.interactive.default_assets_dir`)."""
    run = load_run(run_dir)
    study = run.study
    out = Path(out) if out else default_report_dir(run_dir)
    out.mkdir(parents=True, exist_ok=True)
    a = analyse(run, noise_z=noise_z)
    to_csv_columns(study, a.front).to_csv(out / "pareto.csv", index=False)  # unit suffixes, SI values
    figs = make_figures(run, a)
    plot_structures(figs, run, a)  # a study over structures (report/structures.py)
    try:
        viewer = viewer_data(run, a)
    except Exception as e:  # the interactive view must not cost the report
        viewer = None
        figs.items.append(("viewer_error", f"interactive view unavailable: {e}", b""))
    secs = sections(run, a)
    secs[-1:-1] = [Section(t, x, Table.of(d) if d is not None and len(d) else None)
                   for t, x, d in [*structure_sections(run, a), *robust_sections(run, a)]]
    (out / "img").mkdir(exist_ok=True)
    for name, _, png in figs.items:
        if png:
            (out / "img" / f"{name}.png").write_bytes(png)
    (out / "report.md").write_text(render_markdown(run, secs, figs, interactive=viewer is not None))
    script = plotly_script(out, assets) if viewer is not None else None
    (out / "index.html").write_text(render_html(run, secs, figs, viewer, script))
    return out
