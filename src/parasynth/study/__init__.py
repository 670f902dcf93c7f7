"""Design studies from YAML: schema, evaluation, runners and result tables."""

from .evaluate import Evaluator, Record
from .runner import RunResult, read_journal, results_table, run_study
from .spec import OPTIMIZERS, ResolvedStudy, StudyError, StudySpec, load_study, resolve_study

__all__ = ["load_study", "resolve_study", "run_study", "StudyError", "StudySpec", "ResolvedStudy", "Evaluator",
           "Record", "RunResult", "results_table", "read_journal", "OPTIMIZERS"]
