"""Study reports, written from a run directory (:mod:`parasynth.study.rundir`). The Pareto
maths (:mod:`parasynth.pareto`) is re-exported here for existing imports."""

from ..pareto import (NoisyComparison, compare_with_noise, default_reference_point, hypervolume, knee_index,
                      non_dominated_ranks, pareto_mask, reference_standing, to_min)
from .render import ReportError, load_run, write_report

__all__ = ["compare_with_noise", "NoisyComparison", "write_report", "load_run", "ReportError", "pareto_mask", "non_dominated_ranks", "hypervolume",
           "default_reference_point", "knee_index", "reference_standing", "to_min"]
