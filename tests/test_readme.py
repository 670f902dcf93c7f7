"""The README's quick start: two commands, a clean clone, and what a newcomer needs to know."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def _quick_start() -> str:
    return README.split("## Quick start")[1].split("\n## ")[0]


def test_quick_start_has_exactly_two_commands():
    block = re.search(r"```bash\n(.*?)```", _quick_start(), re.S).group(1)
    lines = [ln for ln in block.splitlines() if ln.strip()]
    assert len(lines) == 2
    assert "parasynth run studies/quickstart.yaml" in lines[0] and "pytest" in lines[1]


def test_quick_start_report_does_not_dirty_the_clone():
    block = re.search(r"```bash\n(.*?)```", _quick_start(), re.S).group(1)
    first = block.splitlines()[0]
    m = re.search(r"--(?:report-dir|out) (\S+)", first)
    assert m is None or not m.group(1).startswith("reports/"), "the quick start must not write the committed reports"
    # where the report goes: the run directory (runs/<name>/, git-ignored) holds it in report/
    name = re.search(r"^name:\s*(\S+)", (ROOT / "studies" / "quickstart.yaml").read_text(), re.M).group(1)
    ignored = (ROOT / ".gitignore").read_text().split()
    assert "runs/" in ignored
    assert f"`runs/{name}/report/index.html`" in _quick_start()
    assert "runs/<name>/, its report in runs/<name>/report/" in README


def test_quick_start_names_python_venv_and_test_duration():
    qs = _quick_start()
    assert "3.11" in qs and "venv" in qs
    # the test suite's time on 2 cores, within the project's 8-minute limit
    m = re.search(r"about (\d+) minutes on 2 cores", qs)
    assert m and 1 <= int(m.group(1)) <= 8, m


def test_workers_example_says_when_workers_pay_off():
    part = README.split("--workers 2")[1][:900]
    # measured speed-ups for a long and the short study, and when spawned workers do not pay off
    assert "1,000 quick-start" in part and "80-design quick" in part
    assert "pay off only" in part and "1-3 s to start" in part
