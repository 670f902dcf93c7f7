"""What a design of a study is, in one place, below the study schema and the evaluator:

* :func:`design_params` -- design values -> the mechanism's parameters (the study's fixed
  parameters, the design variables, and the tied parameters that follow a variable);
* :func:`design_key` -- the identity of a design (two rows or records with the same key are
  the same design);
* :func:`box_centre` -- the centre of the design space (log scale and integers respected; a study
  over structures at its reference structure), defined in :mod:`.structure_space`;
* :func:`evaluation_sample` -- the workspace sample of a design, one
  :class:`~parasynth.measures.workspace.WorkspaceSample` built from the study's evaluation section;
* :func:`measure_arguments` -- the keyword arguments of a measure for a design: that sample
  (with the fields the measure's settings override) where the measure takes one, and the
  measure's own settings. Nothing is merged by name: each setting's declaration
  (:class:`~parasynth.measures.measure_spec.Setting`) says whether it sets a field of the sample
  (``sample_field``) or defaults to an evaluation key (``evaluation_key``);
* :func:`measure_settings` -- the same as the older flat call form (``measure(mech, **flat)``);
* :func:`design_mechanism` -- the mechanism of a design: the model with the design's
  parameters and the pose constraints the study adds (``evaluation.constraints``).

The functions take a resolved study (:class:`~parasynth.study.spec.ResolvedStudy`) by its
attributes; of the study layer this module imports only the design space
(:mod:`parasynth.study.space`, where the identity and the centre are defined).
"""

from __future__ import annotations

import dataclasses

from ..model.constraints import SingularityMarginFloor
from ..mechanisms import instantiate, mechanism_class
from ..measures.objectives import get as get_measure
from ..measures.workspace import WorkspaceSample
from .space import BOX_CENTRE_U, centre_value
from .structure_space import box_centre
from .space import design_key as key_of

__all__ = ["design_params", "design_key", "BOX_CENTRE_U", "centre_value", "box_centre", "evaluation_sample",
           "measure_arguments", "measure_settings", "design_mechanism", "study_class", "with_pose_constraints"]


def design_params(study, values: dict) -> dict:
    """Parameters of the mechanism for design ``values``: the fixed parameters, the design
    values, and each tied parameter set to the variable it follows (the task's variables,
    ``task.*``, are not the mechanism's: :func:`design_task`)."""
    params = {**study.fixed, **{k: v for k, v in values.items() if not str(k).startswith("task.")}}
    for k, src in study.tied.items():
        if src in values:
            params[k] = values[src]
    return params


def design_key(study, values) -> tuple:
    """Identity of a design of ``study`` (:func:`parasynth.study.space.design_key` over the
    study's variables). ``values`` is a mapping or a table row."""
    return key_of(study.variables, values)


def evaluation_sample(study, n: int | None = None, seed: int | None = None) -> WorkspaceSample:
    """The workspace sample of the study's evaluation section (``ranges``, ``n``, ``method``,
    ``seed``, ``fixed`` pose), with ``n`` and ``seed`` replaced when given (a re-evaluation)."""
    ev = study.evaluation
    return WorkspaceSample(ranges=ev.get("ranges"), n=ev["n"] if n is None else n, method=ev["method"],
                           seed=ev["seed"] if seed is None else seed, fixed=ev.get("fixed"))


def design_task(study, values: dict | None = None):
    """The study's task (``study.task``, a :class:`parasynth.Task`) with the design's task
    variables (``task.placement.z``, ``task.tool.yaw``, ...) applied; None without a task."""
    task = getattr(study, "task", None)
    if task is None:
        return None
    own = {str(k)[5:]: float(v) for k, v in (values or {}).items() if str(k).startswith("task.")}
    return task.with_settings(own) if own else task


def measure_arguments(study, measure_name: str, settings: dict, sample: WorkspaceSample,
                      pinned: tuple = (), task=None) -> dict:
    """Keyword arguments of measure ``measure_name`` for one design: ``sample=`` the design's
    workspace sample (with the fields the measure's ``settings`` override, except those in
    ``pinned``, e.g. ``n`` and ``seed`` of a re-evaluation) where the measure takes one, the
    measure's own settings, and the study's evaluation value of each own setting declared with
    an ``evaluation_key`` that ``settings`` leave out; a task measure's ``task`` is ``task`` (the
    design's, :func:`design_task`), else the study's."""
    m = get_measure(measure_name)
    out = m.own(settings)
    for k, p in m.params.items():
        if p.kind == "task" and k not in out:
            out[k] = task if task is not None else getattr(study, "task", None)
    for k, p in m.params.items():
        if p.evaluation_key and k not in out and study.evaluation.get(p.evaluation_key) is not None:
            out[k] = study.evaluation[p.evaluation_key]
    if m.sample:
        over = {f: v for f, v in m.sample_overrides(settings).items() if f not in pinned}
        out["sample"] = dataclasses.replace(sample, **over) if over else sample
    return out


def measure_settings(study, measure_name: str, own: dict, n: int | None = None, seed: int | None = None) -> dict:
    """Settings of measure ``measure_name`` in the older flat call form
    (``measure(mech, **settings)``, the same value as :func:`measure_arguments`): the fields of
    its workspace sample under the names of the settings that set them (an accuracy measure's
    sampling method as ``sampling``), then its own settings."""
    m = get_measure(measure_name)
    pinned = tuple(f for f, v in (("n", n), ("seed", seed)) if v is not None)
    args = measure_arguments(study, measure_name, own, evaluation_sample(study, n, seed), pinned)
    sample = args.pop("sample", None)
    if sample is None:
        return args
    name_of = {p.sample_field: k for k, p in m.params.items() if p.sample_field}
    flat = {name_of[f]: v for f, v in sample.kwargs().items() if v is not None and f in name_of}
    return {**flat, **args}


def with_pose_constraints(study, mech):
    """``mech`` with the pose constraints the study adds in ``evaluation.constraints`` (a
    :class:`~parasynth.model.constraints.SingularityMarginFloor` per ``{type: singularity_margin,
    min: ...}``); ``mech`` itself when it adds none."""
    added = study.evaluation.get("added_constraints") or ()
    if not added:
        return mech
    return mech.with_constraints(*(SingularityMarginFloor(a["name"], floor=a["min"],
                                                          doc=f"singularity margin >= {a['min']:g} (the study's)")
                                   for a in added))


#: The model class of each study seen (by id, with the study kept alive so that its id stays its own).
_CLASSES: dict = {}


def study_class(study) -> type:
    """The model class of ``study.mechanism``, resolved once per study object: every design of a
    run is built from the same class (a description file edited during a run does not change
    the model halfway through it), without a look at the file per design."""
    hit = _CLASSES.get(id(study))
    if hit is not None and hit[0] is study:
        return hit[1]
    cls = mechanism_class(study.mechanism)
    if len(_CLASSES) >= 64:
        _CLASSES.clear()
    _CLASSES[id(study)] = (study, cls)
    return cls


def design_mechanism(study, values: dict):
    """The mechanism of design ``values`` of ``study``: the model (:func:`study_class`) built with
    :func:`design_params` and the study's added pose constraints (:func:`with_pose_constraints`)."""
    return with_pose_constraints(study, instantiate(study_class(study), study.mechanism, **design_params(study, values)))
