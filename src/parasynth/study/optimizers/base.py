"""The optimiser contract and the registry of optimisers (``optimizer.kind``).

An optimiser is one class in one module of :mod:`parasynth.study.optimizers`, derived from
:class:`BaseOptimizer` and registered with ``@register("kind")``. The modules of the package
are found when the registry is first read, so adding an optimiser touches its module (and its
test and docs page) only. The spec's allowed kinds and algorithms (:data:`ALGORITHMS`,
``parasynth list``), the checks of the ``optimizer:`` section, the budget, the planned designs
and the run all come from the registered class.

The contract (every method but :meth:`BaseOptimizer.run` has a default):

* class attributes: ``kind`` (set by :func:`register`), ``title`` (how messages name a run of
  it), ``algorithms`` (allowed ``optimizer.algorithm`` values, the first the default),
  ``budget_key`` (the ``optimizer`` field holding the budget, or None when the designs are
  listed), ``default_budget``, ``lists_designs`` (it evaluates a fixed list of designs, each
  once: the final re-evaluation takes them all), ``uses_storage`` (an external storage and
  worker processes: ``--storage``/``--workers`` apply), ``runs_structures`` (it can run a
  ``structure:`` study), ``halving`` (it spreads its budget over the structures by successive
  halving: ``structure.screening``/``eta``/``keep`` apply), ``description`` (one line for
  the docs and ``parasynth list``);
* :meth:`check` (classmethod): check the study's ``optimizer:`` section against the resolved
  variables and objectives; raise :class:`~parasynth.study.errors.StudyError` naming the field
  and what is allowed; :meth:`check_structures`: the same for a ``structure:`` study (refused
  by name unless ``runs_structures``); :meth:`algorithm`: the algorithm a study runs;
* :meth:`budget` / :meth:`planned_designs` (classmethods): the designs a run may evaluate, the
  designs a finished run holds (None when it may stop early);
* :meth:`open`: open or resume the optimiser's storage before any work and return the records
  the run starts from (default: the run directory's journal as read);
* :meth:`run`: evaluate designs only through the :class:`~parasynth.study.problem.Problem`
  (``problem.evaluate``), hand every record to ``ctx.record``, skip or replay ``ctx.records``
  on resume, evaluate inside ``ctx.guard.evaluating()`` and stop when ``ctx.guard.requested``;
* :meth:`stored_reference` / :meth:`stored_final` / :meth:`stored_polished`: hooks after the
  reference design, the final re-evaluation and each design of the polish (an optimiser with
  its own storage keeps them there); :meth:`polish_trial`: the trial number of the next
  polish design;
* :meth:`searches_globally` (classmethod): whether ``optimizer.polish`` may refine its result.
"""

from __future__ import annotations

import importlib
import pkgutil
from abc import ABC, abstractmethod
from collections.abc import Mapping
from typing import ClassVar

from ..errors import StudyError

__all__ = ["BaseOptimizer", "register", "optimizer_class", "kinds", "registered", "ALGORITHMS"]

_REGISTRY: dict[str, type] = {}
_DISCOVERED = [False]


class BaseOptimizer(ABC):
    """One optimiser: see the module docstring for the contract."""

    kind: ClassVar[str] = ""
    title: ClassVar[str] = ""
    algorithms: ClassVar[tuple[str, ...]] = ()
    budget_key: ClassVar[str | None] = "n_trials"
    default_budget: ClassVar[int | None] = None
    lists_designs: ClassVar[bool] = False
    uses_storage: ClassVar[bool] = False
    runs_structures: ClassVar[bool] = False
    halving: ClassVar[bool] = False
    description: ClassVar[str] = ""

    # -- the study file ------------------------------------------------------------------------------
    @classmethod
    def check(cls, opt, variables, objectives, space) -> None:
        """Check ``opt`` (the ``optimizer:`` section) against the resolved ``variables`` and
        ``objectives``; the algorithm is checked against :attr:`algorithms` before."""

    @classmethod
    def check_structures(cls, opt) -> None:
        """A ``structure:`` study: refused by name unless :attr:`runs_structures`."""
        if not cls.runs_structures:
            raise StudyError(f"optimizer.kind: {cls.kind} cannot run a study over structures (structure:); use "
                             f"{' or '.join(k for k in kinds() if optimizer_class(k).runs_structures)}")

    @classmethod
    def algorithm(cls, study) -> str | None:
        """``optimizer.algorithm``, else the default (the first of :attr:`algorithms`)."""
        return study.optimizer.algorithm or (cls.algorithms[0] if cls.algorithms else None)

    @classmethod
    def budget(cls, study, n_trials: int | None = None) -> int:
        """Designs a run may evaluate: ``n_trials`` (``--n-trials``), else the study's budget
        field, else :attr:`default_budget`."""
        given = getattr(study.optimizer, cls.budget_key) if cls.budget_key else None
        return int(n_trials or given or cls.default_budget)

    @classmethod
    def planned_designs(cls, study) -> int | None:
        """Designs a finished run holds with its own budget; None when it may stop early."""
        return cls.budget(study)

    # -- a run ---------------------------------------------------------------------------------------
    def open(self, problem, out_dir, resume: bool, n_trials, storage, records: list) -> list:
        """Open or resume the optimiser's storage; the records the run starts from."""
        if storage:
            raise StudyError(f"--storage applies to optimisers with a storage; a {self.kind} run keeps its designs "
                             f"in the run directory's journal")
        return records

    @abstractmethod
    def run(self, problem, ctx) -> None:
        """Search: evaluate designs through ``problem``, record them with ``ctx.record``."""

    def stored_reference(self, rec) -> None:
        """The reference design was evaluated (``rec``)."""

    def stored_final(self, out_dir) -> None:
        """``final.csv`` was written in ``out_dir``."""

    def stored_polished(self, rec) -> None:
        """A design of the polish was evaluated (``rec``, already recorded in the journal)."""

    def polish_trial(self, records) -> int:
        """The trial number of the next design of the polish: after every trial of the run."""
        return 1 + max((r.trial for r in records if r.source == "run"), default=-1)

    @classmethod
    def searches_globally(cls, opt) -> bool:
        """Whether the optimiser of the ``optimizer:`` section ``opt`` searches the whole box
        (``optimizer.polish`` refines the result of a global search only)."""
        return True

    @property
    def storage_url(self) -> str | None:
        """The storage URL when given explicitly (the resume hint names it)."""
        return None


def register(kind: str):
    """Class decorator: register an optimiser under ``optimizer.kind: <kind>``."""
    def deco(cls):
        if kind in _REGISTRY and _REGISTRY[kind] is not cls:
            raise ValueError(f"optimizer kind {kind!r} is registered twice")
        cls.kind = kind
        _REGISTRY[kind] = cls
        return cls
    return deco


def _discover() -> None:
    """Import every module of this package once (each registers its optimiser)."""
    if _DISCOVERED[0]:
        return
    _DISCOVERED[0] = True
    pkg = __name__.rsplit(".", 1)[0]
    for mod in sorted(pkgutil.iter_modules(importlib.import_module(pkg).__path__), key=lambda m: m.name):
        if not mod.name.startswith("_") and mod.name != "base":
            # lazy: the optimiser modules import the problem, which imports the spec that reads this registry
            importlib.import_module(f"{pkg}.{mod.name}")


def registered() -> dict[str, type]:
    """kind -> optimiser class, in registration order (sweep, nlopt, optuna first)."""
    _discover()
    order = [k for k in ("sweep", "nlopt", "optuna") if k in _REGISTRY]
    return {k: _REGISTRY[k] for k in order + sorted(set(_REGISTRY) - set(order))}


def kinds() -> tuple[str, ...]:
    return tuple(registered())


def optimizer_class(kind: str) -> type[BaseOptimizer]:
    """The optimiser registered as ``kind``; :class:`StudyError` naming the allowed kinds."""
    reg = registered()
    if kind not in reg:
        raise StudyError(f"optimizer.kind: {kind!r} is not an optimiser; allowed: {', '.join(reg)}")
    return reg[kind]


class _Algorithms(Mapping):
    """kind -> its algorithms, read from the registry (``spec.OPTIMIZERS``)."""

    def __getitem__(self, kind):
        return registered()[kind].algorithms

    def __iter__(self):
        return iter(registered())

    def __len__(self):
        return len(registered())

    def __repr__(self):
        return repr(dict(self.items()))


ALGORITHMS = _Algorithms()
