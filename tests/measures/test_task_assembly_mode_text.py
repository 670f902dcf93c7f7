"""The run summary's verification line says when the dense re-check skips the assembly-mode
check (an under-actuated mechanism: the 4-UPS/1-RPS has 4 actuators for 5 freedoms), as the
dense re-check's own line does."""

from pathlib import Path

import parasynth
from parasynth.measures.task import ASSEMBLY_MODE_SKIPPED, assembly_mode_checked
from parasynth.report.summary import verification_text
from parasynth.study import load_study

ROOT = Path(__file__).resolve().parents[2]


def test_the_counts_decide():
    grinder = parasynth.load_mechanism("4ups_1rps")
    gs = parasynth.load_mechanism("gough_stewart_6ups")
    assert (grinder.n_actuators, grinder.n_task) == (4, 5) and not assembly_mode_checked(grinder)
    assert (gs.n_actuators, gs.n_task) == (6, 6) and assembly_mode_checked(gs)


def test_the_summary_line_says_when_the_assembly_mode_is_not_checked():
    under = verification_text(load_study(str(ROOT / "studies" / "4ups_1rps_task.yaml")), {})
    assert ASSEMBLY_MODE_SKIPPED in under and "no change of assembly mode" not in under
    full = verification_text(load_study(str(ROOT / "studies" / "naval_testbed.yaml")), {})
    assert "no change of assembly mode" in full and ASSEMBLY_MODE_SKIPPED not in full
