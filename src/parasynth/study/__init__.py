"""Design studies from YAML: schema, evaluation, runners and result tables."""

from .evaluate import Evaluator, Record
from .journal import read_journal
from .runner import RunResult, run_study
from .spec import OPTIMIZERS, ResolvedStudy, StudyError, StudySpec, load_study, resolve_study
from .tables import results_table

__all__ = ["load_study", "resolve_study", "run_study", "StudyError", "StudySpec", "ResolvedStudy", "Evaluator",
           "Record", "RunResult", "results_table", "read_journal", "OPTIMIZERS"]
