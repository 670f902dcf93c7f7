"""Study reports, written from a run directory (:mod:`parasynth.study.rundir`): the analysis
(:mod:`.analysis`, a typed :class:`Analysis`), the figures (:mod:`.figures`), the sections
(:mod:`.sections`, :mod:`.tables`) and the Jinja2 templates (:mod:`.render`). The Pareto
maths (:mod:`parasynth.common.pareto`) is re-exported here for existing imports."""

from ..common.pareto import (NoisyComparison, compare_with_noise, default_reference_point, hypervolume, knee_index,
                             non_dominated_ranks, pareto_mask, reference_standing, to_min)
from .analysis import Analysis, FinalAnalysis, analyse
from .render import ReportError, load_run, write_report

__all__ = ["analyse", "Analysis", "FinalAnalysis", "compare_with_noise", "NoisyComparison", "write_report", "load_run",
           "ReportError", "pareto_mask", "non_dominated_ranks", "hypervolume", "default_reference_point", "knee_index",
           "reference_standing", "to_min"]
